// Tests for forces (to be written).
