// Tests for j2_mean (to be written).
