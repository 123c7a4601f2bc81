"""Traffic lanes: stop points and ports, voyage segmentation, resampling, DBSCAN lanes."""
