"""The matching-strategy interface and its registry, keyed by name (as CNES CARS registers one application
class per method, `Application.register`, and Pandora its matching costs, `register_subclass`).

A strategy matches a StereoSet tile by tile in two rounds on the chosen execution, driven by
tiled_rounds.match_in_tiles:

1. `match_tile(job, index, box, out, quota)`, a task per tile: the tile's points, numbered 1 ... n, written to the
   work file `out` (tiled_rounds.save_work); it returns a dict with at least "points" (their count) and, for a
   scene-wide orientation bias, "sample": image positions of up to `quota` of them.
2. `between(job, first, outs, rounds, feedback)`, in the step's process: whatever needs every tile's first round
   (a consistency test's sigmas, the orientation bias fitted to the tiles' samples, further short rounds on
   `rounds` over the work files `outs`); returns the job of round 2 and each tile's point count after `keep`.
3. Per tile again: `keep(job, out)` selects the points kept (None: all), the driver numbers them on from the tiles
   before, `refine(job, points)` may change them in place (MPGC) and returns its counts, and the part is written.
4. `stats(job, rounds, feedback)`: the run's MatchStats from the RoundResults `rounds`.

The tasks are static methods and the job a picklable value: they run in threads, local processes or on a Dask
cluster (execution.py). A fourth strategy is a module with a MatchingStrategy subclass decorated by `register`,
and one import line in algorithms/matching_strategies.py (docs/architecture.md, "A matching strategy")."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from operator import attrgetter
from typing import Any, Callable, ClassVar, NamedTuple, TypeVar

import numpy as np

from ..errors import InputError
from ..progress import Feedback
from .match_stats import MatchStats
from .points import MultiPoints
from .stereo_set import StereoSet


class TilePlan(NamedTuple):
    """What `plan` gives the driver: the job every tile shares, the tiles (the strategy's boxes), and each
    tile's quota of sampled points (zeros where no sample is needed)."""

    job: Any
    boxes: list[Any]
    quotas: list[int]


class RoundResults(NamedTuple):
    """What the rounds of a run gave: each tile's round-1 result (`first`), round-2 refinement counts (`refined`,
    `refine`'s) and kept points (`counts`), in tile order."""

    first: list[dict[str, Any]]
    refined: list[dict[str, Any]]
    counts: list[int]


#: runs one more round of tasks on the step's workers: rounds(function, [arguments per task], what) -> results
Rounds = Callable[[Callable[..., Any], Sequence[tuple], str], list[Any]]


class MatchingStrategy(ABC):
    """One way of matching a stereo set (module docstring). Subclasses set `name` (the key of the registry and
    of pushbroom:matchpoints' STRATEGY; the dialog's labels are the plugin's), `settings_type` (a dataclass with a
    check() that raises InputError and returns the settings), `spacing_setting` and the labels of the rounds."""

    name: ClassVar[str]
    settings_type: ClassVar[type[Any]]
    first_round: ClassVar[str] = "matching"
    second_round: ClassVar[str] = "numbering the points"
    #: the setting that is the points' spacing in the reference image (px), a dotted path into the settings
    spacing_setting: ClassVar[str]
    #: the share (%) of the step's progress that round 1 takes
    first_share: ClassVar[float] = 90.0

    @classmethod
    def settings(cls, settings: Any = None) -> Any:
        """`settings` checked (None: the defaults); InputError for another strategy's settings."""
        settings = cls.settings_type() if settings is None else settings
        if not isinstance(settings, cls.settings_type):
            raise InputError(
                f"the {cls.name} strategy takes {cls.settings_type.__name__}, got {type(settings).__name__}"
            )
        return settings.check()

    @classmethod
    def spacing(cls, settings: Any) -> float:
        """The spacing of the points in the reference image (px): the setting `spacing_setting` names."""
        return float(attrgetter(cls.spacing_setting)(settings))

    @classmethod
    @abstractmethod
    def plan(cls, stereo: StereoSet, settings: Any, feedback: Feedback | None) -> TilePlan:
        """The job and the tiles of a run (InputError for inputs the strategy cannot match)."""

    @staticmethod
    @abstractmethod
    def match_tile(job: Any, index: int, box: Any, out: str, quota: int) -> dict[str, Any]:
        """Task, round 1 (module docstring)."""

    @classmethod
    def between(
        cls, job: Any, first: list[dict[str, Any]], outs: list[str], rounds: Rounds, feedback: Feedback | None
    ) -> tuple[Any, list[int]]:
        """Between the rounds (module docstring); by default the job as it is and every point kept."""
        return job, [int(t["points"]) for t in first]

    @staticmethod
    def keep(job: Any, out: str) -> np.ndarray | None:
        """The points of the work file `out` kept in round 2 (bool mask), None: all."""
        return None

    @staticmethod
    def refine(job: Any, points: MultiPoints) -> dict[str, Any]:
        """Round 2's change of a tile's numbered points in place; returns its counts ({}: none)."""
        return {}

    @classmethod
    @abstractmethod
    def stats(cls, job: Any, rounds: RoundResults, feedback: Feedback | None) -> MatchStats:
        """The run's statistics (and its closing log line)."""


S = TypeVar("S", bound=type[MatchingStrategy])
_REGISTRY: dict[str, type[MatchingStrategy]] = {}


def register(cls: S) -> S:
    """Class decorator: register a MatchingStrategy under its `name` (ValueError for a name taken by another)."""
    taken = _REGISTRY.get(cls.name)
    if taken is not None and taken is not cls:
        raise ValueError(f"the matching strategy name {cls.name!r} is taken by {taken.__qualname__}")
    _REGISTRY[cls.name] = cls
    return cls


def registered() -> dict[str, type[MatchingStrategy]]:
    """The registered strategies by name, in the order of their registration."""
    return dict(_REGISTRY)


def strategy_named(name: str) -> type[MatchingStrategy]:
    """The strategy registered as `name`; InputError naming the registered ones otherwise."""
    if name not in _REGISTRY:
        raise InputError(f"the matching strategy must be one of {', '.join(_REGISTRY)}, got {name!r}")
    return _REGISTRY[name]
