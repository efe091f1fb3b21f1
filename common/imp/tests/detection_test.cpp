// Tests for detection (to be written).
