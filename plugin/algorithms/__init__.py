"""One thin QgsProcessingAlgorithm per photogrammetric step."""


def algorithm_classes():
    """The algorithm classes the provider registers, in toolbox order."""
    from .create_block import CreateBlock
    from .simulate_scene import SimulateScene
    return [SimulateScene, CreateBlock]
