"""The images a matching strategy matches: a stereo pair or triplet in combination order (reference, forward[,
backward]) with their sensor models, block ids, names and the height range searched."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Callable

from ..errors import InputError
from ..height_range import GivenHeights, HeightRange
from .points import MultiPoints


@dataclass(frozen=True)
class StereoSet:
    """images: paths, arrays or Image-likes; models: their sensor models; ids: their block image ids; names:
    their names (for the log); heights: the range searched along the rays; tie_points: reads the block's tie
    points (the seeds a strategy may ask for), or None where there are none to read."""

    images: tuple[Any, ...]
    models: tuple[Any, ...]
    ids: tuple[int, ...]
    names: tuple[str, ...]
    heights: HeightRange
    tie_points: Callable[[], MultiPoints] | None = None

    @classmethod
    def of(
        cls,
        images: Sequence[Any],
        models: Sequence[Any],
        names: Sequence[str] | None = None,
        ids: Sequence[int] | None = None,
        heights: GivenHeights | HeightRange = None,
        tie_points: Callable[[], MultiPoints] | None = None,
    ) -> StereoSet:
        """The set of 2 or 3 `images` with a model each (InputError otherwise); names default to "image k", ids
        to 1 ... n; `heights` as given, resolved once with the reference model (HeightRange.resolve)."""
        n = len(images)
        if n not in (2, 3) or len(models) != n:
            raise InputError(
                f"matching takes 2 or 3 images (reference, forward[, backward]) with a sensor model "
                f"each, got {n} image(s) and {len(models)} model(s)"
            )
        return cls(
            tuple(images),
            tuple(models),
            tuple(int(i) for i in (ids or range(1, n + 1))),
            tuple(names or [f"image {k + 1}" for k in range(n)]),
            HeightRange.resolve(heights, models[0]),
            tie_points,
        )

    @property
    def triplet(self) -> bool:
        """Three images (reference, forward, backward)."""
        return len(self.images) == 3

    def __len__(self) -> int:
        return len(self.images)

    def without_loader(self) -> StereoSet:
        """The set without its tie point reader: what tiles share (the reader holds the block)."""
        return StereoSet(self.images, self.models, self.ids, self.names, self.heights)
