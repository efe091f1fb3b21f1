// Tests for star_id (to be written).
