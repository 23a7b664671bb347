"""The batch's record and its claim on the output folder.

``manifest.jsonl`` gets one JSON line per event, flushed to the disk before the next item counts:
``inferred`` (a photo's bundle), ``start`` (an item about to be handed to a worker, with the outputs
it will write), ``done`` or ``failed`` (its outputs with their SHA-256, the seconds of each stage,
the one-line error), ``sheet`` (the contact sheet written). A batch killed at any moment leaves whole
lines but perhaps the last; that line is ignored.
A rerun skips the items whose last ``done`` has the same key and whose outputs are still the files
it wrote. The lock (``.relight-batch.lock``, :mod:`viewer.files.output_lock`: an flock the kernel drops when the
process dies, even by SIGKILL) keeps a second batch out of the folder."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

from viewer.files.ownership import file_sha256

MANIFEST = "manifest.jsonl"
LOCK = ".relight-batch.lock"


def batch_lock(folder):
    """The batch folder held for one batch at a time (:class:`viewer.files.output_lock.ExclusiveLock` on its
    ``LOCK``, which stays, as the manifest does)."""
    from viewer.files.output_lock import ExclusiveLock

    return ExclusiveLock(folder, path=Path(folder) / LOCK, remove=False, busy="wait for it, or give another -o")


class Manifest:
    """Appends events to ``folder/manifest.jsonl`` and reads back what earlier runs finished."""

    def __init__(self, folder: Path):
        self.path = Path(folder) / MANIFEST
        self.events = list(read_events(self.path))
        self._file = None

    def __enter__(self):
        self._file = open(self.path, "a", encoding="utf-8")
        if self._file.tell() > 0:  # a line a kill cut short is ended, so the next event starts its own
            with open(self.path, "rb") as f:
                f.seek(-1, os.SEEK_END)
                if f.read(1) != b"\n":
                    self._file.write("\n")
        return self

    def __exit__(self, *exc):
        self._file.close()

    def add(self, event: str, **fields) -> dict:
        record = {"event": event, "time": round(time.time(), 3), **fields}
        self._file.write(json.dumps(record, sort_keys=True) + "\n")
        self._file.flush()
        os.fsync(self._file.fileno())
        self.events.append(record)
        return record

    def finished(self) -> dict[str, dict]:
        """Item name -> its last ``done`` event."""
        return {e["item"]: e for e in self.events if e.get("event") == "done"}

    def unfinished_starts(self) -> list[dict]:
        """``start`` events with no ``done`` or ``failed`` after them (the items in flight when a
        batch was killed)."""
        open_starts: dict[str, dict] = {}
        for e in self.events:
            if e.get("event") == "start":
                open_starts[e["item"]] = e
            elif e.get("event") in ("done", "failed"):
                open_starts.pop(e["item"], None)
        return list(open_starts.values())


def read_events(path: Path):
    """The manifest's whole lines (a last line cut by a kill is left out)."""
    if not path.is_file():
        return
    with open(path, encoding="utf-8") as f:
        for line in f:
            try:
                record = json.loads(line)
            except ValueError:
                continue
            if isinstance(record, dict) and "event" in record and "item" in record:
                yield record


def still_done(done: dict | None, key: str, folder: Path) -> bool:
    """Whether an item finished by an earlier run with this key still has its outputs as written
    (their size and time as recorded, else their SHA-256)."""
    if done is None or done.get("key") != key or not done.get("sha256"):
        return False
    stamps = done.get("stamps", {})
    for rel, sha in done["sha256"].items():
        path = folder / rel
        if not path.is_file():
            return False
        if stamps.get(rel) != stamp(path) and file_sha256(path) != sha:
            return False
    return True


def stamp(path: Path) -> list:
    st = path.stat()
    return [st.st_size, st.st_mtime_ns]


class Ownership:
    """Which existing files the batches of this folder wrote: outputs recorded with their SHA-256
    (in ``done`` events, or in ``failed`` ones when an item failed after writing some), and the
    outputs of items started and never finished (a killed batch's)."""

    def __init__(self, manifest: Manifest):
        self.hashes: dict[str, set] = {}
        for e in manifest.events:
            for rel, sha in e.get("sha256", {}).items():
                self.hashes.setdefault(rel, set()).add(sha)
        self.claimed = {rel for e in manifest.unfinished_starts() for rel in e.get("outputs", [])}

    def ours(self, folder: Path, rel: str) -> bool:
        """Whether ``folder/rel`` (which exists) is the batches'."""
        return rel in self.claimed or (rel in self.hashes and file_sha256(folder / rel) in self.hashes[rel])
