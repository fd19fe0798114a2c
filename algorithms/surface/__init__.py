"""Object points: forward intersection, point clouds, DEMs."""
