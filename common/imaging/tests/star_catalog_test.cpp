// Tests for star_catalog (to be written).
