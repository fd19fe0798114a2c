"""Session data of the real-data tests, computed once per run and shared read-only: region growing
on the Ventoux pair (test_dsm_real, test_coarse_to_fine_real, test_dense_real, test_height_search_real),
region growing's triplet DSMs (the same and test_matching_pleiades), the triplet's terrain heights found by
matching and dense matching's triplet DSMs over them (test_dense_real, test_height_search_real)."""

import itertools

import pytest

from pushbroom.algorithms import sensors
from pushbroom.algorithms.matching.height_search import search_heights
from pushbroom.algorithms.matching.imagery import Image
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.region_growing_strategy import match_block
from tests.helpers.feedback import Feedback
from tests.helpers.pleiades_scene import NAMES, in_order
from tests.helpers.real_dsm import (
    CELL,
    RG_MAX_EDGE,
    TRIPLET_STEP,
    VENTOUX_CELL,
    VENTOUX_STEP,
    build_triplet_dsms,
    cut,
    dense_pair_of_triplet,
    dense_points,
    refined,
    srtm_comparison,
)


@pytest.fixture(scope="session")
def ventoux_region_growing(ventoux_pair, tmp_path_factory):
    """Region growing on the Ventoux pair, nodes every VENTOUX_STEP px: (MultiPoints, their Intersection
    with the supplied RPCs, real_dsm.srtm_comparison of its 1, VENTOUX_CELL and 5 m DSMs)."""
    models = [sensors.load(p) for p in ventoux_pair]
    points = match_block(
        [Image(p) for p in ventoux_pair],
        models,
        names=[p.stem for p in ventoux_pair],
        params=GrowParams(step=VENTOUX_STEP),
        workers=2,
    )
    result = cut({1: models[0], 2: models[1]}, points.observations)
    srtm = str(ventoux_pair[0].with_name("N44E005.hgt"))
    return (
        points,
        result,
        srtm_comparison(
            result, srtm, (1.0, VENTOUX_CELL, 5.0), VENTOUX_CELL, tmp_path_factory.mktemp("ventoux_region_growing")
        ),
    )


@pytest.fixture(scope="session")
def region_growing_triplet_dsms(pleiades_triplet, tmp_path_factory):
    """real_dsm.build_triplet_dsms of region growing (nodes every TRIPLET_STEP px, CELL m cells, gaps
    beyond RG_MAX_EDGE m)."""

    def match(images, models, names):
        return match_block(images, models, names=names, params=GrowParams(step=TRIPLET_STEP), workers=2)

    return build_triplet_dsms(
        pleiades_triplet, match, CELL, RG_MAX_EDGE, tmp_path_factory.mktemp("rg_triplet_dsm"), Feedback()
    )


@pytest.fixture(scope="session")
def triplet_heights_found(pleiades_triplet):
    """matching.height_search.search_heights on the triplet (combination order): the terrain height range
    createblock finds with no DEM and no height given."""
    paths = in_order(pleiades_triplet)
    return search_heights(paths, [sensors.load(p) for p in paths], list(NAMES))


@pytest.fixture(scope="session")
def dense_triplet_dsms(pleiades_triplet, triplet_heights_found, tmp_path_factory):
    """real_dsm.build_triplet_dsms of dense matching (the LSM-refined dense points, real_dsm.refined)
    over the height range found (triplet_heights_found), as the product matches a block created without a DEM or
    a height; "log": its timings and counts."""
    folder, runs, log, triplet = tmp_path_factory.mktemp("dense_triplet_dsm"), itertools.count(), Feedback(), {}

    def match(images, models, names):
        # the triplet comes first (build_triplet_dsms); its pairs with the reference are its own pairs'
        if len(names) == 2 and names[0] == NAMES[0] and triplet:
            return refined(dense_pair_of_triplet(triplet["points"], list(NAMES).index(names[1])))
        points, _ = dense_points(
            images, models, names, folder / f"dense-{next(runs)}", triplet_heights_found.height_range
        )
        if len(names) == 3:
            triplet["points"] = points
        return refined(points)

    return {**build_triplet_dsms(pleiades_triplet, match, CELL, RG_MAX_EDGE, folder, log), "log": log.messages}
