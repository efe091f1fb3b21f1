// qmethod (to be written)
