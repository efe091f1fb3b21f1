// Tests for shadow (to be written).
