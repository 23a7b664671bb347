"""A clip's inference in a batch spread over the pool's workers: its ranges (:mod:`viewer.photo.clip_ranges`)
handed out as tasks, their results gathered, the clip bundle finished when the last is in."""

from __future__ import annotations

from pathlib import Path

from viewer.errors import InputError


class SplitClip:
    """One clip's ranges in flight. :meth:`open` makes the bundle ready (in the driver: the shots are
    found there), :attr:`tasks` are the workers', :meth:`take` gathers each result and says, when the
    last is in, what an inference task would have (``ok``, ``bundle``, ``cached``, ``seconds``, ``error``)."""

    def __init__(self, clip: Path, bundle: Path, ranges: list, done: dict | None = None):
        self.clip, self.bundle, self.ranges = clip, bundle, ranges
        self.results: list[dict | None] = [None] * len(ranges)
        self.done = done  # what the inference gave, once known

    @classmethod
    def open(cls, clip: Path, settings: dict, workers: int) -> SplitClip:
        """The clip's bundle in the cache made ready for ``workers`` ranges; a clip that cannot be read
        (or a bundle already whole) is done at once."""
        from viewer.files.ownership import file_sha256
        from viewer.photo.clip_inference import cached_clip_path
        from viewer.photo.clip_ranges import open_ranges
        from viewer.photo.photo_frame import WORK_PERSON

        try:
            digest = file_sha256(clip)
            bundle = cached_clip_path(clip, settings["bundles"], 0.0, None, WORK_PERSON, settings["max_size"], digest=digest)
            bundle, ranges, earlier = open_ranges(clip, bundle, workers, max_size=settings["max_size"], digest=digest)
        except InputError as exc:
            return cls(clip, Path(), [], {"ok": False, "error": str(exc)})
        except OSError as exc:
            return cls(clip, Path(), [], {"ok": False, "error": f"{clip}: cannot be read ({exc.strerror or exc})"})
        split = cls(clip, bundle, ranges)
        if earlier is not None:
            split.done = {"ok": True, "bundle": str(bundle), "cached": True, "seconds": 0.0}
        return split

    def tasks(self, settings: dict) -> list[dict]:
        """Each range's task (without its id)."""
        return [{"kind": "infer_range", "photo": str(self.clip), "bundle": str(self.bundle), "range": r.to_json(),
                 "device": settings.get("device", "cpu")} for r in self.ranges]

    def take(self, index: int, result: dict) -> dict | None:
        """Range ``index``'s result; when it is the last, the clip's inference result (the bundle
        finished when every range went well, else the first failure's line)."""
        from viewer.photo.clip_ranges import finish_ranges

        self.results[index] = result
        if any(r is None for r in self.results):
            return None
        failed = next((r for r in self.results if not r["ok"]), None)
        if failed is not None:
            self.done = {"ok": False, "error": failed["error"]}
            return self.done
        try:
            record = finish_ranges(self.clip, self.bundle, self.ranges, [r["range_result"] for r in self.results])
        except InputError as exc:
            self.done = {"ok": False, "error": str(exc)}
            return self.done
        self.done = {"ok": True, "bundle": str(self.bundle), "cached": record["frames_kept_from_earlier_run"] == record["frames"],
                     "seconds": round(sum(r["seconds"] for r in self.results), 3), "ranges": len(self.ranges)}
        return self.done
