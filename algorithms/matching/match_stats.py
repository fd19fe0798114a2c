"""The statistics of a matching run, as the matching step stores them beside the points (block/points.py,
the point folder's index) and reads them back for the points-per-group summary (group_summary.py).

The fields every strategy fills are typed; what only one strategy reports (region growing's LSM attempts,
coarse-to-fine's pyramid levels, dense matching's refined positions) lies in `details`, stored as it is."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any


@dataclass
class MatchStats:
    """strategy: its registered name; images: the block ids in combination order; points: the points kept;
    spacing_px: the strategy's spacing in the reference image (the store compares a new run with the stored
    points at it: block/replacement.py); matched_3: group 3 candidates before the consistency test (region
    growing); sigma_factor, sigma_dx, sigma_dy: the consistency test's factor and robust sigmas (px);
    refined_mpgc: the three-ray points MPGC refined (None: MPGC did not run)."""

    strategy: str
    images: list[int]
    points: int = 0
    spacing_px: float | None = None
    matched_3: int | None = None
    sigma_factor: float | None = None
    sigma_dx: float | None = None
    sigma_dy: float | None = None
    refined_mpgc: int | None = None
    details: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """The flat dict stored with the points: the fields that are set, then the details."""
        typed = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "details"}
        return {**{k: v for k, v in typed.items() if v is not None}, **self.details}

    @classmethod
    def from_dict(cls, stored: dict[str, Any] | None) -> MatchStats:
        """The MatchStats of a stored dict (as_dict's, or an older point folder's: missing fields are None)."""
        stored = dict(stored or {})
        names = {f.name for f in fields(cls)} - {"details"}
        typed = {k: stored.pop(k) for k in list(stored) if k in names}
        typed.setdefault("strategy", "")
        typed.setdefault("images", [])
        return cls(**typed, details=stored)
