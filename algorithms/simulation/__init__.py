"""Scene simulator: the project's ground truth (see scene.py for the products it writes).

    from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
    paths = simulate_scene(SceneConfig(configuration="spot5_triplet", size_km=20), "out/")

Modules: orbit (analytic orbit and attitude), instruments (SPOT 5 triplet, SPOT 1-4 pair, look
angles), acquisition (orbit and timing over the scene), truth (continuous per-image geometry and its
sampling into a SpotOrientation), terrain (Jacksboro DEM, land cover, surface objects), radiometry
(reflectance, sun shading, sensor), render (ray casting against the DSM), tiled_surface (ray casting
in windows of a DSM too large to hold), tiles (ground grids in memory or in files, tile by tile),
points (control/check point candidates), perturbation (known orientation errors), outputs (writers),
sun, noise, grid."""

from .scene import SceneConfig, simulate_scene

__all__ = ["SceneConfig", "simulate_scene"]
