"""Progress bars for long work: one tqdm bar per stage, on stderr (silent when not a terminal
unless forced)."""

from __future__ import annotations

import sys


class StageBars:
    """A ``progress(stage, done, total)`` callback that shows one bar per stage."""

    def __init__(self, prefix: str = "", disable: bool | None = None):
        self.prefix = prefix
        self.disable = (not sys.stderr.isatty()) if disable is None else disable
        self.stage = None
        self.bar = None

    def __call__(self, stage: str, done: int, total: int):
        from tqdm import tqdm

        if stage != self.stage:
            self.close()
            self.stage = stage
            self.bar = tqdm(total=total, desc=f"{self.prefix}{stage}", unit="step", leave=False,
                            disable=self.disable, file=sys.stderr)
        self.bar.update(done - self.bar.n)

    def close(self):
        if self.bar is not None:
            self.bar.close()
            self.bar = None
            self.stage = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
