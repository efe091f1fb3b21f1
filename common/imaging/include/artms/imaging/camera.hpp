// camera (to be written)
