// Tests for ephemeris (to be written).
