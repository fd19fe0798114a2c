"""Statistical outlier removal of a point cloud (Rusu et al. 2008; PCL's StatisticalOutlierRemoval, PDAL's
filters.statisticaloutlier, the statistical filter of CNES CARS).

Per point i, d_i is the mean 3-D distance (metres; x, y in a local frame, z the height) to its k nearest other
points. Over the whole cloud, with mu and s the mean and standard deviation of d:

    point i is an outlier  <=>  d_i > mu + n s.

An isolated blunder (a point metres above or below the surface its neighbours agree on) has a large d_i; a
point of a dense, consistent surface a small one. mu and s are the cloud's, summed over its tiles, so a tile's
decision does not depend on the tiling; a tile's d needs the points within `margin` (module function) around it.
Failure modes: where the cloud is sparse (a gap's edge, a lake's shore) d grows with the spacing, not with an
error, so n should stay large enough (3, the default, leaves 0.3 % of a normal cloud); on a surface sampled far
more densely in one place than another (two strategies' points merged), mu and s mix the two densities.

Reference: R. B. Rusu, Z. C. Marton, N. Blodow, M. Dolha, M. Beetz, "Towards 3D point cloud based object maps for
household environments", Robotics and Autonomous Systems 56(11), 2008."""

import numpy as np
from scipy.spatial import cKDTree

#: default k and n (module docstring)
NEIGHBOURS, FACTOR = 20, 3.0
#: the margin's multiple of the distance to the k-th neighbour of an evenly spread cloud
MARGIN_FACTOR = 4.0


def margin(count, area, k):
    """The margin (m) a tile of `count` points over `area` m^2 needs for its points' k nearest neighbours:
    MARGIN_FACTOR x the radius of a disc holding k + 1 points at the tile's mean density."""
    if count <= 0 or area <= 0:
        return 0.0
    return MARGIN_FACTOR * float(np.sqrt((k + 1) * area / (np.pi * count)))


def mean_distances(context, query, k):
    """Per query point (n, 3 array: x, y, z m), d: the mean distance to its k nearest points of `context` (m, 3),
    which holds the query points themselves (each one's own zero distance is left out). NaN where the context
    has k points or fewer."""
    query = np.asarray(query, float).reshape(-1, 3)
    out = np.full(len(query), np.nan)
    if len(context) <= k or len(query) == 0:
        return out
    dist, _ = cKDTree(np.asarray(context, float)).query(query, k=k + 1)
    return dist[:, 1:].mean(axis=1)


def threshold(count, total, squares, factor):
    """mu + n s of the cloud's d from their count, sum and sum of squares."""
    mu = total / count
    return mu + factor * np.sqrt(max(squares / count - mu * mu, 0.0))
