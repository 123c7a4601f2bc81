"""AIS readers, cleaning, stop points and ports, voyage segmentation, DBSCAN traffic lanes."""
