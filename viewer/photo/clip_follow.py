"""A clip's inference in a child process, handing each frame to a relighting that follows it.

``relight render CLIP`` inferred the whole clip, then relit it: on two cores the inference kept
about 1.2 of them busy and the relighting (llvmpipe) about 1.35, each waiting for the other. Here
the inference runs in a spawned child (:func:`viewer.photo.clip_inference.infer_clip`, exactly as in
one process: the same bundle, resumable the same way) that tells its parent on a pipe each frame
it has finished; the parent relights a frame as soon as it is final
(:func:`viewer.output.clip_render.render_clip`'s ``follow``): inferred, and the frame with a person
it shows known (a frame without one shows the nearest frame with one, earlier first). The frames
relit are those the whole bundle makes, bit for bit.

The child dies with its parent (the kernel kills it, a SIGKILL included) and ignores the terminal's
Ctrl-C, which is the parent's to handle: the parent kills it, and a frame cut short is not there
(each is written whole), so the same command goes on from the last finished frame. Its warnings are
one line each, as the parent's. Once the child runs, the parent lowers its own priority
(``RELIGHT_NICE``): the clip goes at the inference's pace, and beside a relighting at the same
priority the inference's torch and llvmpipe stages were 30-60 % slower (docs/video.md).
"""

from __future__ import annotations

import multiprocessing
from pathlib import Path

from viewer.errors import OUT_OF_MEMORY, InputError, task_error
from viewer.scene.clip_bundle import FRAMES, ClipBundle, absolute_pan, frame_name, load_clip_bundle, read_frame_entry, read_record

RELIGHT_NICE = 10  # the parent's lower priority once its child infers (for the rest of the process's life)
POLL_SECONDS = 0.25  # the longest a wait on the child lasts before a stop is seen
REFUSAL_WAIT = 5.0  # seconds a relighting that failed waits for the child's own word on why


def _infer(conn, parent: int, threads: int, clip: str, target: str, options: dict) -> None:
    """The child: the clip's bundle inferred into ``target``, each finished frame said on ``conn``
    (("frame", done, total)), then ("done", record), or ("refused", path, problem) for an input error,
    or ("failed", line) for anything else."""
    import os
    import signal
    import warnings

    from viewer.cores import size_pools
    from viewer.errors import one_line_warning
    from viewer.stop_signals import die_with_parent

    die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    warnings.showwarning = one_line_warning  # (as the parent's: relight.cli.main)
    if os.getppid() != parent:  # the parent went before the request took effect
        return
    size_pools(threads)
    from viewer.photo.clip_inference import infer_clip

    try:
        record = infer_clip(clip, target, progress=lambda done, total, entry: conn.send(("frame", done, total)), **options)
        conn.send(("done", record))
    except InputError as exc:
        conn.send(("refused", exc.path, exc.problem))
    except MemoryError:
        conn.send(("refused", None, OUT_OF_MEMORY))
    except OSError as exc:  # the system refused a read or a write the checks could not foresee
        conn.send(("refused", exc.filename, exc.strerror or str(exc)))
    except Exception as exc:  # noqa: BLE001 - a fault of the program's: its trace here, the parent stops on it
        import sys
        import traceback

        traceback.print_exc(file=sys.stderr)
        conn.send(("failed", task_error(exc)))


class FollowedInference:
    """The clip bundle of ``clip`` being inferred into ``target`` by a child process (``options``:
    :func:`viewer.photo.clip_inference.infer_clip`'s); call it with a frame's index (:meth:`__call__`)
    to wait for that frame. ``progress(done, total)`` as frames are finished; :attr:`record` once
    the inference has ended. :meth:`close` ends the child."""

    def __init__(self, clip, target, options: dict, threads: int, progress=None):
        import os

        self.target, self.progress = Path(target), progress
        self.total = 0  # the frames the clip is expected to hold (its header's estimate), until the inference ends
        self.record: dict | None = None
        self._known = 0  # frames final: inferred in this run, in order
        self._entries: list = []
        self._record: dict | None = None  # the bundle's record as the child wrote it before its first frame
        self._people = 0  # of them, frames with a person
        self._bundle: ClipBundle | None = None
        self._whole: ClipBundle | None = None
        mp = multiprocessing.get_context("spawn")
        self._conn, theirs = mp.Pipe(duplex=False)
        self._child = mp.Process(target=_infer, args=(theirs, os.getpid(), threads, str(clip), str(target), options), daemon=True)
        self._child.start()
        theirs.close()
        try:  # the clip goes at the inference's pace: the relighting takes what the child leaves of the cores
            os.nice(RELIGHT_NICE)
        except OSError:
            pass

    def close(self) -> None:
        if self._child.is_alive():
            self._child.kill()
        self._child.join()
        self._conn.close()

    def __call__(self, index: int) -> ClipBundle:
        """The clip bundle once frame ``index`` is final (it and a frame with a person inferred: the
        frames it holds are the clip's first, each as the whole bundle will hold it), or the whole bundle
        when the inference has ended; waits for it (what the child said meanwhile read first: its
        progress shown as it goes, and its pipe never full)."""
        while self._whole is None and self._conn.poll():
            self._receive()
        while True:
            if self._whole is not None:
                return self._whole
            if index < self._known and self._people:
                return self._bundle
            self._receive()

    def wait(self) -> dict:
        """The inference's record, once it has ended (frames relit or not)."""
        while self.record is None:
            self._receive()
        return self.record

    def _receive(self) -> None:
        """The child's next message, waited for in short waits: a stop (Ctrl-C, SIGTERM) reaches this
        thread between them (:mod:`viewer.stop_signals`), not only when the child next speaks."""
        try:
            while not self._conn.poll(POLL_SECONDS):
                if not self._child.is_alive() and not self._conn.poll():
                    raise EOFError
            message = self._conn.recv()
        except (EOFError, OSError):
            self._child.join()
            raise InputError(None, f"the clip's inference ended without a word (exit code {self._child.exitcode}: killed, "
                                   "or out of memory?): run again to go on from its last frame") from None
        kind = message[0]
        if kind == "frame":
            self._grow(message[1])
            self.total = max(message[2], message[1])
            if self.progress is not None:
                self.progress(message[1], self.total)
        elif kind == "done":
            self.record = message[1]
            self._whole = load_clip_bundle(self.target)
            self.total = len(self._whole.frames)
        elif kind == "refused":
            raise InputError(message[1], message[2])
        else:
            raise RuntimeError(f"the clip's inference (a child process) failed: {message[1]} (its trace is above)")

    def refusal(self, wait: float = REFUSAL_WAIT) -> InputError | None:
        """What the child says went wrong, waited for up to ``wait`` seconds, or None: a relighting that failed on a
        frame the child has just taken away (the clip changed while it was inferred) says the child's reason,
        not a missing file's."""
        import time

        deadline = time.monotonic() + wait
        try:
            while time.monotonic() < deadline:
                if self._conn.poll(0.05):
                    message = self._conn.recv()  # (frames said meanwhile are not read: they may be gone)
                    if message[0] == "refused":
                        return InputError(message[1], message[2])
                    if message[0] != "frame":
                        return None
                elif not self._child.is_alive():
                    return None
        except (EOFError, OSError):
            return None
        return None

    def _grow(self, known: int) -> None:
        """Frames up to ``known`` (excluded) read: each finished in this run, its record written before it was said."""
        if self._record is None:  # (rewritten only once the inference has ended)
            self._record = read_record(self.target)
        for i in range(self._known, known):
            entry = absolute_pan(read_frame_entry(self.target / FRAMES / f"{frame_name(i)}.json"), self._record, self.target)
            self._entries.append(entry)
            self._people += entry.state == "person"
        self._known = known
        self._bundle = ClipBundle(self.target, self._record, tuple(self._entries))
