"""crs.transform hands PROJ its points in chunks: the chunks give every point as one call does."""
import numpy as np

from pushbroom.algorithms import crs


def test_chunked_transform_equals_one_call(monkeypatch):
    rng = np.random.default_rng(5)
    lonlat = np.column_stack([rng.uniform(2.0, 4.0, 1000), rng.uniform(43.0, 45.0, 1000), rng.uniform(0, 900, 1000)])
    whole = crs.transform(crs.srs(4979), crs.srs(4978), lonlat, "test points")
    monkeypatch.setattr(crs, "TRANSFORM_CHUNK", 64)     # 16 chunks, the last one short
    chunked = crs.transform(crs.srs(4979), crs.srs(4978), lonlat, "test points")
    assert chunked.shape == (1000, 3) and np.array_equal(chunked, whole)
    assert np.abs(np.linalg.norm(whole, axis=1) - 6.37e6).max() < 3e4      # ECEF radii: the transform ran
