// Tests for qmethod (to be written).
