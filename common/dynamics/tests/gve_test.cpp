// Tests for gve (to be written).
