"""A clip's inferred frames written as they come (:class:`FrameWrites`: on a thread, in order, each
frame's entry after its maps) and the warnings its frames raise said once each (:class:`FrameWarnings`)."""

from __future__ import annotations

import collections
import contextlib
import functools
import queue
import threading


class FrameWrites:
    """A clip's frames written in order on a thread of their own while the next frame is inferred (a
    frame's bundle, then its record, each put after the one before it). Writing took 0.15 s of a
    1280x720 frame's 2.1 s, the encoders (zlib, OpenEXR) outside the interpreter's lock. A write that
    fails is raised by the next :meth:`put`, :meth:`deliver` or :meth:`close`, and what was put after
    it is not written (a frame's record never without its bundle). At most ``AHEAD`` writes wait."""

    AHEAD = 3

    def __init__(self):
        self._queue: queue.Queue = queue.Queue(maxsize=self.AHEAD)
        self._error: BaseException | None = None  # the write that failed, until raised
        self._failed = False  # a write failed: nothing after it is written (stays set once raised)
        self._ready: collections.deque = collections.deque()  # calls whose writes are done, for the caller's thread
        self._thread = threading.Thread(target=self._loop, name="frame-writes", daemon=True)
        self._thread.start()

    def put(self, write) -> None:
        self.deliver()
        self._queue.put(write)

    def after(self, call) -> None:
        """``call()`` on the caller's thread once every write put before it is done (a frame's progress:
        the next frame's reader sees it whole), at the next :meth:`deliver`, :meth:`put` or :meth:`close`."""
        self.put(functools.partial(self._ready.append, call))

    def deliver(self) -> None:
        """The calls whose writes are done, made; a write that failed, raised."""
        self._raise_pending()
        while self._ready:
            self._ready.popleft()()

    def close(self, quiet: bool = False) -> None:
        """Wait for every write put; raise the first that failed (``quiet``: not, another exception is on
        its way out); make the calls left."""
        self._queue.put(None)
        self._thread.join()
        if quiet:
            self._error = None
        self.deliver()

    def _loop(self) -> None:
        while (write := self._queue.get()) is not None:
            if not self._failed:
                try:
                    write()
                except BaseException as exc:  # noqa: BLE001 - raised on the inference's thread
                    self._error, self._failed = exc, True

    def _raise_pending(self) -> None:
        if self._error is not None:
            error, self._error = self._error, None
            raise error


class FrameWarnings:
    """A clip's frames warn as photos do, each naming its frame ("CLIP at 1.5 s: the person is
    sideways ..."): a warning is shown for the first frame that gives it, and at the end one line says
    how many more frames gave it (a long clip printed a line a frame)."""

    def __init__(self, clip_path):
        self.clip_path = clip_path
        self.counts: dict[tuple, int] = {}

    @contextlib.contextmanager
    def frame(self, label: str):
        import warnings

        caught: list = []
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                yield
        finally:  # (a frame with no person raises, after its warnings)
            for w in caught:
                key = (w.category, str(w.message).replace(label, "", 1).lstrip(": "))
                self.counts[key] = self.counts.get(key, 0) + 1
                if self.counts[key] == 1:
                    warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)

    def close(self) -> None:
        import warnings

        for (category, text), count in self.counts.items():
            if count > 1:
                warnings.warn(f"{self.clip_path}: {count - 1} more frame{'s' if count > 2 else ''}: {text}", category, stacklevel=2)
        self.counts.clear()
