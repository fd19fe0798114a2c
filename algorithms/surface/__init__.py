"""Object points: forward intersection, point clouds, DEMs (methods.md sections 5-6)."""
