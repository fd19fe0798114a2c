"""Whether a step's new result may replace what the block holds: a step that finds nothing, or far fewer than
before, never replaces good results silently. points.store_point_parts (mass and tie points) and
control_points.save_control_points (control/check points and their measurements) ask `check_replacement`
before they switch to the new result.

A new result is *far fewer* when one of its counts (points; measured points; image measurements) is below
FAR_FEWER, half, of what the stored result gives under the new settings: the stored count, scaled down
where the new run samples more coarsely (a matching STEP or a tie point CELL twice as large expects a
quarter of the points: `expected`), never scaled up (a finer run that finds more than half of the stored
points is not refused). Why a half: a rerun with other thresholds, seeds or images moves a count by tens of
per cent; a run that failed (a height range beside the terrain, a point group no point reaches, a file
without measurement columns) loses most or all of it.

Such a result is refused with an InputError: the block keeps its stored result, layer and counts, and
nothing new is left behind. An error, not a warning: a script or a graphical model stops there instead of
running the next steps on nothing. With `replace_fewer` (the steps' REPLACE_FEWER) it is stored, with a
warning. Where nothing (or nothing readable) is stored, any result is stored."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from .. import progress
from ..errors import InputError
from ..progress import Feedback

#: a new count below this share of the stored one (scaled by `Tally.expected`) is far fewer
FAR_FEWER = 0.5


@dataclass(frozen=True)
class Tally:
    """One count of the stored result and of the new one that would replace it."""

    name: str  # what is counted, plural ("mass points")
    stored: int
    new: int
    expected: float | None = None  # the stored result's count under the new settings (None: `stored`)

    @property
    def reference(self) -> float:
        """The count the new one is compared with: `expected`, at most `stored`."""
        return float(self.stored) if self.expected is None else min(float(self.expected), float(self.stored))

    @property
    def far_fewer(self) -> bool:
        return self.stored > 0 and self.new < FAR_FEWER * self.reference

    def __str__(self) -> str:
        text = f"{self.new} {self.name} against {self.stored}"
        if self.reference < self.stored:
            text += f", about {self.reference:.0f} at the new, coarser spacing"
        return text


def check_replacement(
    tallies: Sequence[Tally],
    replace_fewer: bool,
    what: str,
    step: str,
    hint: str = "",
    feedback: Feedback | None = None,
) -> None:
    """Refuse (InputError) a new result of which a count is far fewer than the stored one's (module docstring),
    unless `replace_fewer`: then warn through `feedback`. `what`: the stored result ("mass points"); `step`: the
    step that makes it, named in the message; `hint`: another way out, one sentence."""
    fewer = [t for t in tallies if t.far_fewer]
    if not fewer:
        return
    found = "; ".join(map(str, fewer))
    if replace_fewer:
        progress.warn(
            feedback,
            f"the new {what} are far fewer than the block's ({found}): they replace them, as REPLACE_FEWER asks",
        )
        return
    kept = ", ".join(f"{t.stored} {t.name}" for t in tallies if t.stored)
    raise InputError(
        f"the new {what} are far fewer than the block's ({found}; far fewer: below {FAR_FEWER:.0%}): "
        f"nothing was stored, and the block keeps its {kept}. Check the parameters and the messages "
        f"above. {hint + ' ' if hint else ''}To replace them anyway, run {step} again with REPLACE_FEWER "
        "set (an advanced parameter)"
    )
