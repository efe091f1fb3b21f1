// Tests for camera (to be written).
