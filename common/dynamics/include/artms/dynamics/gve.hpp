// gve
