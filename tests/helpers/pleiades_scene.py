"""The Pleiades triplet of the real test data (pleiades_triplet) as the real-data tests match it: in
combination order (reference, forward, backward) = (img_02, img_01, img_03), block image ids 1, 2,
3 (test_matching_pleiades.test_reference_is_the_most_nadir gives the reasons); the session's matching of it is
tests/real/conftest.py's (match_block from automatic seeds in every tile over the RPCs' own height range)."""

from pushbroom.algorithms import sensors

ORDER = (2, 1, 3)  # img_02 reference (nadir), img_01 forward, img_03 backward
NAMES = [f"img_0{k}" for k in ORDER]
#: block image id -> name (match_block's default ids 1, 2, 3 in combination order)
LABELS = {k + 1: name for k, name in enumerate(NAMES)}


def in_order(triplet):
    """The paths of the `pleiades_triplet` fixture (file order) in combination order."""
    return [triplet[k - 1] for k in ORDER]


def triplet_models(triplet):
    """{block image id: RpcModel}, freshly loaded (the adjustment edits its models)."""
    return {k + 1: sensors.load(p) for k, p in enumerate(in_order(triplet))}
