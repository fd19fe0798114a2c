"""One thin QgsProcessingAlgorithm per photogrammetric step."""


def algorithm_classes():
    """The algorithm classes the provider registers, in toolbox order."""
    from .assess_accuracy import AssessAccuracy
    from .bundle_adjust import BundleAdjust
    from .coregister_dem import CoregisterDem
    from .create_block import CreateBlock
    from .extract_dtm import ExtractDtm
    from .fit_rpc import FitRpc
    from .import_points import ExportPoints, ImportPoints
    from .interpolate_dem import InterpolateDem
    from .intersect_points import IntersectPoints
    from .match_points import MatchPoints
    from .merge_dems import MergeDems
    from .orthorectify import Orthorectify
    from .select_tie_points import SelectTiePoints
    from .simulate_scene import SimulateScene

    return [
        SimulateScene,
        CreateBlock,
        MatchPoints,
        SelectTiePoints,
        ImportPoints,
        ExportPoints,
        BundleAdjust,
        IntersectPoints,
        InterpolateDem,
        Orthorectify,
        CoregisterDem,
        MergeDems,
        ExtractDtm,
        AssessAccuracy,
        FitRpc,
    ]
