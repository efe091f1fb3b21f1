// dbscan (to be written)
