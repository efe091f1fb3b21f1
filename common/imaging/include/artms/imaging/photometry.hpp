// photometry (to be written)
