// image (to be written)
