"""A clip's inference in a batch spread over the pool's workers: its ranges (:mod:`viewer.photo.clip_ranges`)
handed out as tasks, their results gathered, the clip bundle finished when the last is in."""

from __future__ import annotations

from pathlib import Path

from viewer.batch.plan import cache_path
from viewer.errors import task_error


class SplitClip:
    """One clip's ranges in flight. :meth:`open` makes the bundle ready (in the driver, which holds the
    bundle's lock until the last range is in: the shots are found there), :meth:`tasks` are the
    workers', :meth:`take` gathers each result and says, when the last is in, what an inference task
    would have (``ok``, ``bundle``, ``cached``, ``seconds``, ``error``)."""

    def __init__(self, clip: Path, bundle=None, done: dict | None = None):
        self.clip, self.bundle = clip, bundle  # a viewer.photo.clip_ranges.RangedBundle
        self.results: list[dict | None] = [None] * (len(bundle.ranges) if bundle is not None else 0)
        self.done = done  # what the inference gave, once known

    @classmethod
    def open(cls, clip: Path, settings: dict, workers: int) -> SplitClip:
        """The clip's bundle in the cache made ready for ``workers`` ranges; a clip that cannot be read
        (or a bundle already whole) is done at once."""
        from viewer.files.ownership import file_sha256
        from viewer.photo.clip_cache import ClipRequest
        from viewer.photo.clip_ranges import open_ranges

        try:
            digest = file_sha256(clip)
            bundle = open_ranges(clip, cache_path(clip, settings["bundles"], settings["max_size"], digest), workers,
                             ClipRequest(max_size=settings["max_size"]), digest, cached=True)
        except Exception as exc:  # noqa: BLE001 - the clip's items fail with its line; the batch goes on
            return cls(clip, None, {"ok": False, "error": task_error(exc)})
        split = cls(clip, bundle)
        if bundle.earlier is not None:
            bundle.close()
            split.done = {"ok": True, "bundle": str(bundle.path), "cached": True, "seconds": 0.0}
        return split

    def tasks(self, settings: dict) -> list[dict]:
        """Each range's task (without its id)."""
        if self.done is not None:
            return []
        key = self.bundle.key
        return [{"kind": "infer_range", "photo": str(self.clip), "bundle": str(self.bundle.path), "range": r.to_json(),
                 "key": key, "device": settings.get("device", "cpu")} for r in self.bundle.ranges]

    def take(self, index: int, result: dict) -> dict | None:
        """Range ``index``'s result; when it is the last, the clip's inference result (the bundle
        finished when every range went well, else the first failure's line)."""
        self.results[index] = result
        if any(r is None for r in self.results):
            return None
        failed = next((r for r in self.results if not r["ok"]), None)
        try:
            if failed is not None:
                self.done = {"ok": False, "error": failed["error"]}
                return self.done
            record = self.bundle.finish(self.clip, [r["range_result"] for r in self.results])
        except Exception as exc:  # noqa: BLE001 - the clip's items fail with its line; the batch goes on
            self.done = {"ok": False, "error": task_error(exc)}
            return self.done
        finally:
            self.close()
        self.done = {"ok": True, "bundle": str(self.bundle.path), "cached": record["frames_kept_from_earlier_run"] == record["frames"],
                     "seconds": round(sum(r["seconds"] for r in self.results), 3), "ranges": len(self.bundle.ranges)}
        return self.done

    def close(self) -> None:
        """The bundle's lock let go (the batch ends, or the clip's ranges are all in)."""
        if self.bundle is not None:
            self.bundle.close()
