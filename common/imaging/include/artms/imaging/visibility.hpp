// visibility (to be written)
