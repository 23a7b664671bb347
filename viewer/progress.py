"""Progress of long work on stderr: one tqdm bar per stage on a terminal, and one line per stage
otherwise (a log file, a pipe), when the stage ends."""

from __future__ import annotations

import sys
import time


class TimeLeft:
    """How far a piece of work of several stages is, and the seconds it has left: each stage's
    expected share of the whole time (``shares``, measured for that work; a stage not listed counts
    nothing) weights its ``done / total``, and the time so far is scaled by what is left."""

    def __init__(self, shares: dict[str, float]):
        total = sum(shares.values()) or 1.0
        self.shares = {stage: share / total for stage, share in shares.items()}
        self.order = list(shares)
        self.started = time.perf_counter()
        self.fraction = 0.0

    def update(self, stage: str, done: int, total: int) -> float:
        """The overall fraction after ``done`` of ``total`` steps of ``stage``."""
        if stage in self.shares:
            before = sum(self.shares[s] for s in self.order[:self.order.index(stage)])
            self.fraction = max(self.fraction, before + self.shares[stage] * min(done / max(total, 1), 1.0))
        return self.fraction

    def seconds_left(self) -> float | None:
        """None until a twentieth of the work is done (too early to say)."""
        if self.fraction < 0.05:
            return None
        return (time.perf_counter() - self.started) * (1.0 - self.fraction) / self.fraction

    def words(self) -> str:
        """The time left as a bar or a line says it; empty when it is too early to say or the work is done."""
        seconds = self.seconds_left()
        if seconds is None or self.fraction >= 1.0:
            return ""
        return "under a second left" if seconds < 1.0 else f"about {seconds:.0f} s left"


class StageBars:
    """A ``progress(stage, done, total)`` callback that shows one bar per stage (a terminal) or
    prints one line as each stage ends (``stage: done/total in N s``); ``quiet`` shows nothing.
    With ``shares`` (the stages' expected shares of the time, :class:`TimeLeft`), the time left
    for the whole work is on the bar and on each line."""

    def __init__(self, prefix: str = "", quiet: bool = False, stream=None, shares: dict[str, float] | None = None):
        self.prefix = prefix
        self.quiet = quiet
        self.stream = stream if stream is not None else sys.stderr
        self.terminal = self.stream.isatty()
        self.stage = None
        self.bar = None
        self.done = self.total = 0
        self.started = 0.0
        self.shares = shares
        self.time_left = None  # started with the first step reported: the work's own time, not its set-up

    def __call__(self, stage: str, done: int, total: int):
        if stage != self.stage:
            self.close()
            self.stage, self.started = stage, time.perf_counter()
            if self.terminal and not self.quiet:
                from tqdm import tqdm

                self.bar = tqdm(total=total, desc=f"{self.prefix}{stage}", unit="step", leave=False, file=self.stream)
        self.done, self.total = done, total
        if self.time_left is None and self.shares:
            self.time_left = TimeLeft(self.shares)
        if self.time_left is not None:
            self.time_left.update(stage, done, total)
        if self.bar is not None:
            if self.time_left is not None:
                self.bar.set_postfix_str(self.time_left.words(), refresh=False)
            self.bar.update(done - self.bar.n)

    def close(self):
        if self.bar is not None:
            self.bar.close()
            self.bar = None
        elif self.stage is not None and not self.quiet:
            left = self.time_left.words() if self.time_left is not None else ""
            print(f"{self.prefix}{self.stage}: {self.done}/{self.total} in {time.perf_counter() - self.started:.1f} s"
                  + (f", {left}" if left else ""), file=self.stream, flush=True)
        self.stage = None

    def __enter__(self):
        return self

    def __exit__(self, exc_type, *exc):
        if exc_type is not None:  # the error's own line says what happened: no "done" line for a stage it cut short
            self.quiet = True
        self.close()
