// Tests for photometry (to be written).
