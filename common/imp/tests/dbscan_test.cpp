// Tests for dbscan (to be written).
