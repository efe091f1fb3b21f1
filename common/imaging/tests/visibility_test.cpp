// Tests for visibility (to be written).
