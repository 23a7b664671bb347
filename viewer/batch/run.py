"""The batch's driver: photos x looks -> items; the items not done yet (by content key) handed to a
pool as an inference per photo, then a render per item as soon as its photo's bundle is there; each
result recorded in the manifest as it arrives; a progress bar with the time left; a summary. With
more than one worker a clip's inference goes in ranges (:mod:`viewer.batch.clip_split`) and each of its
items' relit parts go to the workers (:func:`viewer.batch.spread_clip.part_tasks`) before its render joins
them."""

from __future__ import annotations

import itertools
import re
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from viewer.batch.clip_split import SplitClip
from viewer.batch.contact_sheet import SHEET, contact_sheet
from viewer.batch.manifest import LOCK, MANIFEST, Manifest, Ownership, batch_lock, stamp, still_done
from viewer.batch.plan import Item, LookSpec, clip_bundle_key, item_key, photo_names
from viewer.batch.spread_clip import part_tasks
from viewer.files.clip_reader import is_clip
from viewer.files.output_lock import held_now
from viewer.files.ownership import file_sha256


@dataclass
class ResolvedLook:
    """A look with everything its renders need, found once by the driver (a map's lights fitted or
    taken from the cache once), or the one line saying why it cannot be rendered."""

    spec: LookSpec
    look_json: dict | None = None
    options: dict = field(default_factory=dict)
    lights: np.ndarray | None = None  # (N, 7): direction, sigma, intensity
    rig: np.ndarray | None = None
    source_sha: str = ""
    rig_sha: str = ""
    error: str | None = None
    place: list | None = None  # a plate look: the feet (x, y) and the height, fractions of the plate
    horizon: float | None = None  # ... and the plate's horizon, a fraction of its height (the contact shadow's ground)


@dataclass
class Summary:
    done: int = 0
    failed: int = 0
    skipped: int = 0
    seconds: float = 0.0
    workers: int = 0
    failures: list = field(default_factory=list)  # (item, error)
    sheet: Path | None = None  # the contact sheet, when this run rendered something

    @property
    def per_minute(self) -> float:
        return 60.0 * self.done / self.seconds if self.seconds > 0 else 0.0

    def line(self, manifest: Path) -> str:
        if not self.done and not self.failed:
            return f"batch: nothing to do, {self.skipped} items already done; manifest {manifest}"
        return (f"batch: {self.done} done, {self.failed} failed, {self.skipped} already done, in {self.seconds:.1f} s "
                f"({self.per_minute:.1f} photo-looks a minute, {self.workers} worker{'s' if self.workers != 1 else ''}); "
                f"manifest {manifest}")


LEFTOVER = re.compile(r"^\.(.+)\.\d+\.tmp$")  # .NAME.PID.tmp
KEYLESS = ("bundles",)  # settings that do not change an output (where the bundles are kept)


def plan_items(photos: list[Path], looks: list[ResolvedLook], settings: dict) -> tuple[list[Item], dict[Path, str]]:
    """Every (photo, look) item with its outputs and key; the photos' bundle keys (what their bundles
    are made from: viewer.photo.bundle_version.bundle_key), or for a photo that cannot be read its line."""
    from viewer.errors import InputError
    from viewer.photo.bundle_version import bundle_key, inference_version

    names = photo_names(photos, reserved=(MANIFEST, SHEET, LOCK))
    version = inference_version()
    shas, errors = {}, {}
    for p in photos:
        try:
            shas[p] = clip_bundle_key(file_sha256(p), settings["max_size"], version) if is_clip(p) else \
                bundle_key(p, max_size=settings["max_size"], version=version)
        except InputError as exc:
            shas[p], errors[p] = "", str(exc)
        except OSError as exc:
            shas[p], errors[p] = "", f"{p}: cannot be read ({exc.strerror or exc})"
    items = []
    for p in photos:
        for look in looks:
            name = f"{names[p]}/{look.spec.name}"
            if is_clip(p):  # the relit clip, and its middle frame (what the contact sheet shows)
                outputs = (f"{name}.png", f"{name}.mp4")
            else:
                outputs = (f"{name}.png", f"{name}.exr") + ((f"{name}.layers.exr",) if settings.get("layers") else ())
            item = Item(p, look.spec, name, outputs)
            if look.lights is not None and shas[p]:
                item.settings = {"look": look.look_json, "options": look.options,
                                 **{k: v for k, v in settings.items() if k not in KEYLESS},
                                 **({"place": look.place, "horizon": look.horizon} if look.place is not None else {})}
                item.key = item_key(shas[p], look.source_sha, look.rig_sha,
                                    np.concatenate([look.lights] + ([look.rig] if look.rig is not None else [])), item.settings)
            items.append(item)
    return items, errors


def remove_leftovers(folder: Path, items: list[Item]) -> None:
    """Temporary files a killed batch left beside the outputs it plans (``.NAME.PID.tmp``, the
    atomic writes' names: viewer.files.imageio.atomic_paths); nothing else is touched. Each folder is
    listed once."""
    planned: dict[Path, set] = {}
    for item in items:
        for rel in item.outputs:
            planned.setdefault((folder / rel).parent, set()).add((folder / rel).name)
    for parent, names in planned.items():
        if not parent.is_dir():
            continue
        for tmp in parent.iterdir():
            m = LEFTOVER.match(tmp.name)
            if m and m.group(1) in names and tmp.is_file() and not held_now(parent / m.group(1)):  # (a render writing it now)
                tmp.unlink()


def run_batch(photos: list[Path], looks: list[ResolvedLook], folder, make_pool, settings: dict,
              quiet: bool = False) -> Summary:
    """Render every item not done yet into ``folder``; ``make_pool()`` gives the pool (called only
    when there is work); ``settings``: the options every item shares (max_size, layers, ...)."""
    from tqdm import tqdm

    folder = Path(folder)
    start = time.perf_counter()
    summary = Summary()
    with batch_lock(folder), Manifest(folder) as manifest:
        finished = manifest.finished()
        ownership = Ownership(manifest)
        items, photo_errors = plan_items(photos, looks, settings)
        remove_leftovers(folder, items)
        by_look = {look.spec: look for look in looks}
        todo = []
        for item in items:
            look = by_look[item.look]
            error = look.error or photo_errors.get(item.photo)
            if error is None and still_done(finished.get(item.name), item.key, folder):
                summary.skipped += 1
                continue
            if error is None:
                taken = [rel for rel in item.outputs if (folder / rel).exists() and not ownership.ours(folder, rel)]
                if taken:
                    error = f"{folder / taken[0]}: exists and no relight batch wrote it there: move it away or give another -o"
            if error is not None:
                _failed(manifest, summary, item, error)
            else:
                todo.append(item)
        if todo:
            pool = make_pool()
            summary.workers = pool.size
            try:
                _run(pool, todo, by_look, folder, settings, manifest, summary, quiet, tqdm)
            finally:
                pool.close()
        if summary.done:
            finished = manifest.finished()
            shown = {i.name: finished[i.name] for i in items if i.name in finished and finished[i.name].get("key") == i.key}
            summary.sheet = contact_sheet(folder, shown, Ownership(manifest))
            if summary.sheet is not None:
                manifest.add("sheet", item=SHEET, sha256={SHEET: file_sha256(summary.sheet)})
    summary.seconds = time.perf_counter() - start
    return summary


def _run(pool, todo: list[Item], by_look, folder: Path, settings: dict, manifest: Manifest, summary: Summary, quiet, tqdm):
    bar = tqdm(total=len(todo), unit="item", desc="relighting", disable=quiet, file=sys.stderr, leave=False)
    try:
        _Dispatch(pool, todo, by_look, folder, settings, manifest, summary, bar).run()
    finally:
        bar.close()


class _Dispatch:
    """The batch's tasks handed to the pool's workers and their results taken in: each photo (or clip)
    inferred once (a clip in ranges over the workers), then its items rendered (a clip's relit parts
    spread over the workers, then joined)."""

    def __init__(self, pool, todo: list[Item], by_look, folder: Path, settings: dict, manifest: Manifest, summary: Summary,
                 bar):
        self.pool, self.by_look, self.folder, self.settings = pool, by_look, folder, settings
        self.manifest, self.summary, self.bar = manifest, summary, bar
        self.waiting: dict[Path, list[Item]] = {}
        for item in todo:
            self.waiting.setdefault(item.photo, []).append(item)
        self.tasks: dict[int, tuple[str, object]] = {}
        # clip items whose relit parts are out: their render task, their parts' tasks' fields, left, an error
        self.spread: dict[str, dict] = {}
        self.splits: dict[Path, SplitClip] = {}
        self.ids = itertools.count()

    def submit(self, kind: str, what, task: dict) -> None:
        task_id = next(self.ids)
        self.tasks[task_id] = (kind, what)
        self.pool.submit({**task, "id": task_id})

    def run(self) -> None:
        to_split = []  # clips whose frames go in ranges, one a worker
        for photo in self.waiting:
            if is_clip(photo) and self.pool.size > 1:
                to_split.append(photo)
            else:
                self.submit("infer", photo, {"kind": "infer", "photo": str(photo), "max_size": self.settings["max_size"],
                                             "device": self.settings.get("device", "cpu"), "bundles": self.settings["bundles"],
                                             "clip": is_clip(photo)})
        try:
            while self.tasks or to_split:
                while to_split and len(self.tasks) < self.pool.size:  # opened one at a time (its shots are found here)
                    self.split(to_split.pop(0))
                for r in self.pool.results(timeout=0.5):
                    kind, what = self.tasks.pop(r["id"], (None, None))
                    if kind == "infer":
                        self.inferred(what, r)
                    elif kind == "range":
                        done = self.splits[what[0]].take(what[1], r)
                        if done is not None:
                            self.inferred(what[0], done)
                    elif kind == "open":
                        self.opened(what, r)
                    elif kind == "part":
                        self.part_done(what, r)
                    elif kind == "render":
                        self.rendered(what, r)
        finally:
            for split in self.splits.values():
                split.close()

    def split(self, photo: Path) -> None:
        """A clip's frames handed out in ranges, one a worker."""
        self.splits[photo] = split = SplitClip.open(photo, self.settings, self.pool.size)
        if split.done is not None:
            self.inferred(photo, split.done)
        for k, task in enumerate(split.tasks(self.settings)):
            self.submit("range", (photo, k), task)

    def inferred(self, photo: Path, r: dict) -> None:
        """The photo's (or clip's) bundle is there, or could not be made: its items rendered, or failed."""
        if r["ok"]:
            self.manifest.add("inferred", item=str(photo), bundle=r["bundle"], cached=r["cached"], seconds=r["seconds"],
                              pid=r.get("pid"), **({"ranges": r["ranges"]} if "ranges" in r else {}))
        for item in self.waiting.pop(photo):
            if not r["ok"]:
                _failed(self.manifest, self.summary, item, r["error"])
                self.bar.update(1)
                continue
            self.manifest.add("start", item=item.name, outputs=list(item.outputs))  # before any of it is written
            task = _render_task(item, self.by_look[item.look], r["bundle"], self.folder, self.settings)
            if task["clip"] and self.pool.size > 1:  # its relit parts spread over the workers, then joined by its render
                parts = {**task, "output": str(self.folder / item.outputs[1]), "layers": False}  # (a batch's clip has no layers)
                self.spread[item.name] = {"task": task, "parts": parts, "left": 0, "error": None}
                self.submit("open", item, {**parts, "kind": "open_parts"})
            else:
                self.submit("render", item, task)

    def opened(self, item: Item, r: dict) -> None:
        """A clip item's folders made ready: its relit parts not made yet handed out."""
        if not r["ok"]:
            return self.joined(item, r["error"])
        state = self.spread[item.name]
        for part in part_tasks(state["parts"], [index for index, _, _ in r["parts"]]):
            state["left"] += 1
            self.submit("part", item, part)
        if not state["left"]:
            self.joined(item, None)

    def part_done(self, item: Item, r: dict) -> None:
        state = self.spread[item.name]
        state["left"] -= 1
        state["error"] = state["error"] or (None if r["ok"] else r["error"])
        if not state["left"]:
            self.joined(item, state["error"])

    def joined(self, item: Item, error: str | None) -> None:
        """A clip item's parts all in: its render joins them (and writes its poster), or it failed."""
        state = self.spread.pop(item.name)
        if error is not None:
            _failed(self.manifest, self.summary, item, error, self.folder)
            self.bar.update(1)
        else:
            self.submit("render", item, state["task"])

    def rendered(self, item: Item, r: dict) -> None:
        if r["ok"]:
            self.manifest.add("done", item=item.name, key=item.key, photo=str(item.photo), look=item.look.name,
                              settings=item.settings, outputs=list(item.outputs), sha256=r["sha256"],
                              stamps={rel: stamp(self.folder / rel) for rel in item.outputs},
                              times={**r.get("times", {}), "total": r.get("seconds")}, pid=r.get("pid"))
            self.summary.done += 1
        else:
            _failed(self.manifest, self.summary, item, r["error"], self.folder)
        self.bar.update(1)


def _render_task(item: Item, look: ResolvedLook, bundle: str, folder: Path, settings: dict) -> dict:
    return {"kind": "render", "item": item.name, "bundle": bundle, "folder": str(folder),
            "outputs": list(item.outputs), "envmap": str(look.spec.envmap) if look.spec.envmap else None,
            "lights": look.lights.tolist(), "rig": look.rig.tolist() if look.rig is not None else None,
            "look": look.look_json, "options": look.options, "max_size": settings["max_size"],
            "layers": bool(settings.get("layers")), "per_light": bool(settings.get("per_light")), "clip": is_clip(item.photo),
            **({"plate": str(look.spec.plate), "place": look.place, "horizon": look.horizon, "cut_allowed": settings["cut_allowed"]}
               if look.spec.plate is not None else {})}


def _failed(manifest: Manifest, summary: Summary, item: Item, error: str, folder: Path | None = None):
    """``folder``: the item was handed to a worker (its outputs were checked to be ours or absent),
    so whatever it wrote before failing is recorded as ours, to be replaced by its next try."""
    written = {rel: file_sha256(folder / rel) for rel in item.outputs if (folder / rel).is_file()} if folder else {}
    manifest.add("failed", item=item.name, key=item.key, photo=str(item.photo), look=item.look.name, error=error,
                 **({"sha256": written} if written else {}))
    summary.failed += 1
    summary.failures.append((item.name, error))
