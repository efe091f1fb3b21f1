// Tests for gravity (to be written).
