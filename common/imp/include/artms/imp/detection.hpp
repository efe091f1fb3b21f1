// detection (to be written)
