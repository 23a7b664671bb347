"""How much GL work one call to ``Engine.render`` may do (the window's frames while a new map or a
photo comes in): units of work (a light's shadow map, a band of a group's light pass, a band of the frame...)
run while the time gone plus the next unit's expected cost fits the budget; at least one unit runs
per call. A unit's expected cost is its last measured time (llvmpipe works at the flush, so each unit
is timed to its ``finish``), so a frame never starts a long unit it has no time left for; a kind of
unit not measured yet (a new engine's first frame) is expected to take as long as the longest unit
of the call so far (it counted as free, and a drag preview's first frame ran 30 ms past its budget)."""

from __future__ import annotations

import time


class WorkBudget:
    def __init__(self, ctx, seconds: float | None, costs: dict[str, float]):
        self.ctx, self.seconds, self.costs = ctx, seconds, costs  # costs: the engine's, kept between calls
        self.start = time.perf_counter()
        self.units = 0
        self.longest = 0.0  # the longest unit of this call so far (seconds)
        self._unit, self._unit_start = None, self.start

    def spent(self, unit: str) -> bool:
        """Before a unit of work named ``unit``: True to stop here (never before the first unit)."""
        if self.seconds is None:
            return False
        if self.units:
            now = self._finish()
            if now - self.start + self.costs.get(unit, self.longest) > self.seconds:
                return True
        self.units += 1
        self._unit, self._unit_start = unit, time.perf_counter()
        return False

    def close(self):
        """The last unit's time, once the call's work is done (budgeted calls only)."""
        if self.seconds is not None and self._unit is not None:
            self._finish()
            self._unit = None

    def _finish(self) -> float:
        self.ctx.finish()
        now = time.perf_counter()
        took = self.costs[self._unit] = now - self._unit_start
        self.longest = max(self.longest, took)
        return now


def draw_bands(work: WorkBudget | None, first: int, bands: int, unit: str, draw, check_first: bool = False) -> int | None:
    """A pass drawn in ``bands`` bands of rows from band ``first``, each a unit of ``work`` named
    ``unit`` (``draw(band)`` sets its scissor and draws); without ``work``, one whole draw,
    ``draw(None)``. Returns the band the budget ran out before (the next call starts there), or None
    once every band is drawn. The first band drawn is a unit the caller counted, unless ``check_first``."""
    if work is None:
        draw(None)
        return None
    for band in range(first, bands):
        if (band > first or check_first) and work.spent(unit):
            return band
        draw(band)
    return None
