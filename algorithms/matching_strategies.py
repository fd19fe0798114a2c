"""The built-in matching strategies, registered as their modules are imported (matching/strategy.py). A fourth
strategy is its own module and one import line here (docs/architecture.md, "A matching strategy")."""

from .dense import dense_strategy  # noqa: F401  (registers "dense")
from .matching import (
    coarse_to_fine,  # noqa: F401  (registers "coarse_to_fine")
    region_growing_strategy,  # noqa: F401  (registers "region_growing")
)
from .matching.strategy import registered, strategy_named

__all__ = ["registered", "strategy_named"]
