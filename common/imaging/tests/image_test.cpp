// Tests for image (to be written).
