// Tests for atmosphere (to be written).
