"""Progress of long work on stderr: one tqdm bar per stage on a terminal, and one line per stage
otherwise (a log file, a pipe), when the stage ends."""

from __future__ import annotations

import sys
import time


class StageBars:
    """A ``progress(stage, done, total)`` callback that shows one bar per stage (a terminal) or
    prints one line as each stage ends (``stage: done/total in N s``); ``quiet`` shows nothing."""

    def __init__(self, prefix: str = "", quiet: bool = False, stream=None):
        self.prefix = prefix
        self.quiet = quiet
        self.stream = stream if stream is not None else sys.stderr
        self.terminal = self.stream.isatty()
        self.stage = None
        self.bar = None
        self.done = self.total = 0
        self.started = 0.0

    def __call__(self, stage: str, done: int, total: int):
        if stage != self.stage:
            self.close()
            self.stage, self.started = stage, time.perf_counter()
            if self.terminal and not self.quiet:
                from tqdm import tqdm

                self.bar = tqdm(total=total, desc=f"{self.prefix}{stage}", unit="step", leave=False, file=self.stream)
        self.done, self.total = done, total
        if self.bar is not None:
            self.bar.update(done - self.bar.n)

    def close(self):
        if self.bar is not None:
            self.bar.close()
            self.bar = None
        elif self.stage is not None and not self.quiet:
            print(f"{self.prefix}{self.stage}: {self.done}/{self.total} in {time.perf_counter() - self.started:.1f} s",
                  file=self.stream, flush=True)
        self.stage = None

    def __enter__(self):
        return self

    def __exit__(self, exc_type, *exc):
        if exc_type is not None:  # the error's own line says what happened: no "done" line for a stage it cut short
            self.quiet = True
        self.close()
