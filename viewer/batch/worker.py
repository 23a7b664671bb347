"""A batch worker: one process, one GL context, its threads sized by the batch. It infers a photo's
bundle (the inference cache: once per photo) and renders an item's outputs, keeping the last
scene's engine and the maps it read, so that a photo's looks in a row cost their renders alone.
Tasks and results are plain dicts (they cross process and machine boundaries)."""

from __future__ import annotations

import os
import time
from pathlib import Path

from viewer.errors import InputError, task_error
from viewer.stop_signals import die_with_parent


class Worker:
    def __init__(self, threads: int):
        from viewer.cores import size_pools

        os.environ["LP_NUM_THREADS"] = str(threads)  # llvmpipe reads it when the context is made
        size_pools(threads)
        self._ctx = None
        self._engine_key, self._engine, self._scene = None, None, None
        self._map = (None, None)  # the last map read: (path, pixels)

    @property
    def ctx(self):
        if self._ctx is None:
            from viewer.gl import create_headless_context

            self._ctx = create_headless_context()
        return self._ctx

    def pid(self) -> int:
        return os.getpid()

    def run(self, task: dict) -> dict:
        """Run one task; an error the user can act on comes back as its one line."""
        start = time.perf_counter()
        try:
            result = {"infer": self.infer, "infer_range": self.infer_range, "render": self.render,
                      "open_parts": self.open_parts, "render_parts": self.render_parts}[task["kind"]](task)
            return {**result, "ok": True, "pid": os.getpid(), "seconds": round(time.perf_counter() - start, 3)}
        except InputError as exc:
            return {"ok": False, "error": str(exc), "pid": os.getpid()}
        except Exception as exc:  # noqa: BLE001 - any failure is its item's one line; the worker goes on
            self._drop_engine()  # (a GL error may have left the engine half made)
            return {"ok": False, "error": task_error(exc), "pid": os.getpid()}

    def _drop_engine(self):
        if self._engine is not None:
            try:
                self._engine.release()
            except Exception:  # noqa: BLE001 - a broken engine is dropped all the same
                pass
        self._engine_key, self._engine, self._scene = None, None, None

    def infer(self, task: dict) -> dict:
        if task.get("clip"):
            return self.infer_clip(task)
        from viewer.photo.inference import cached_bundle

        bundle, cached = cached_bundle(task["photo"], None, max_size=task["max_size"], device=task.get("device", "cpu"),
                                       ctx=self.ctx, bundles=task["bundles"])
        return {"bundle": str(bundle), "cached": cached}

    def infer_clip(self, task: dict) -> dict:
        """A clip's bundle in the cache (the whole clip, temporal on), made or finished there."""
        from viewer.batch.plan import cache_path
        from viewer.files.ownership import file_sha256
        from viewer.photo.clip_cache import ClipRequest
        from viewer.photo.clip_inference import infer_clip

        digest = file_sha256(task["photo"])
        bundle = cache_path(task["photo"], task["bundles"], task["max_size"], digest)
        record = infer_clip(task["photo"], bundle, ClipRequest(max_size=task["max_size"]), device=task.get("device", "cpu"),
                            ctx=self.ctx, digest=digest, cached=True)
        return {"bundle": str(bundle), "cached": record["frames_kept_from_earlier_run"] == record["frames"]}

    def infer_range(self, task: dict) -> dict:
        """A range of a clip's frames into its bundle, made ready by the batch (viewer.batch.clip_split)."""
        from viewer.photo.clip_ranges import ClipRange, infer_range

        self._drop_engine()  # (a GL context serves the range's frames)
        result = infer_range(task["photo"], task["bundle"], ClipRange(*task["range"]), task.get("key"), device=task.get("device", "cpu"),
                             ctx=self.ctx)
        return {"range_result": result}

    def _clip_render(self, task: dict):
        """What a clip's render takes, from ``task``: its pictures (:class:`viewer.output.clip_render.ClipPictures`,
        or a plate's)."""
        from viewer.gl.options import EngineOptions
        from viewer.lighting.envmap import load_envmap
        from viewer.scene.area_lights import AreaLights
        from viewer.scene.clip_bundle import load_clip_bundle
        from viewer.scene.look import Look

        self._drop_engine()  # a clip's frames each have their engine
        env = load_envmap(task["envmap"], repair=task.get("repair", False)).pixels if task.get("envmap") else None
        bundle = load_clip_bundle(task["bundle"])
        fixed = AreaLights.from_array(task["rig"]) if task.get("rig") is not None else None
        lights, look, options = AreaLights.from_array(task["lights"]), Look.from_json(task["look"]), EngineOptions(**task["options"])
        sizes, turn = tuple(task.get("sizes") or (None, task["max_size"])), task.get("turn", 0.0)
        if not task.get("plate"):
            from viewer.output.clip_render import ClipPictures

            return ClipPictures(self.ctx, bundle, lights, look, env, fixed, options, turn, sizes)
        from viewer.output.plate_clip import PlatePictures  # the clip's person put into a plate, frame by frame
        from viewer.plate.loader import read_plate
        from viewer.plate.placement import Placement

        return PlatePictures(self.ctx, bundle, lights, look, env, fixed, options, turn, sizes,
                             plate=read_plate(task["plate"], [], task.get("front")).within(task.get("plate_size") or sizes[1]),
                             place=Placement(*task["place"]), horizon=task["horizon"], cut_allowed=task["cut_allowed"])

    def render_clip(self, task: dict) -> dict:
        """A clip item: the relit clip (the map does not turn; the source's framing at --max-size) and
        its middle frame as a PNG."""
        from viewer.files.ownership import file_sha256, refuse_foreign
        from viewer.output.clip_render import render_clip
        from viewer.output.video import audio_sidecar

        t = time.perf_counter()
        folder = Path(task["folder"])
        png, mp4 = (folder / rel for rel in task["outputs"])
        pictures = self._clip_render(task)
        refuse_foreign([audio_sidecar(mp4, pictures.bundle.source["path"])])  # where audio an MP4 cannot hold would go
        result = render_clip(pictures, mp4, poster=png)
        times = {"render": round(time.perf_counter() - t, 3), "frames": result["frames"]}
        return {"times": times, "sha256": {rel: file_sha256(folder / rel) for rel in task["outputs"]},
                **({"note": result["audio_note"]} if result["audio_note"] else {})}

    def open_parts(self, task: dict) -> dict:
        """A clip item's folders made ready for its relit parts; the parts not made yet (each [index,
        first, last]), which the batch hands out (:mod:`viewer.batch.clip_split`)."""
        from viewer.output.clip_render import open_render

        return {"parts": [list(p) for p in open_render(self._clip_render(task), task["output"], layers=task.get("layers", False),
                                                       per_light=task.get("per_light", False))]}

    def render_parts(self, task: dict) -> dict:
        """Some parts of a relit clip (``relight render CLIP --ray``: :mod:`viewer.batch.spread_clip`),
        into the parts folder its driver made ready."""
        from viewer.output.clip_render import render_clip

        return render_clip(self._clip_render(task), task["output"], layers=task.get("layers", False),
                           per_light=task.get("per_light", False), only=task["parts"])

    def render(self, task: dict) -> dict:
        """An item: its outputs held for the item's run (:mod:`viewer.files.output_lock`: a render writing one of
        them now is said in the item's line, not mixed with), then rendered."""
        import contextlib

        from viewer.files.output_lock import ExclusiveLock
        from viewer.output.video import partial_path

        folder = Path(task["folder"])
        paths = [folder / rel for rel in task["outputs"]]
        with contextlib.ExitStack() as held:
            for p in paths + [partial_path(p) for p in paths if p.suffix == ".mp4"]:
                held.enter_context(ExclusiveLock(p))
            return self.render_clip(task) if task.get("clip") else self._render_photo(task)

    def _render_photo(self, task: dict) -> dict:
        from viewer.files.ownership import file_sha256
        from viewer.gl import Engine
        from viewer.gl.options import EngineOptions
        from viewer.lighting.envmap import load_envmap
        from viewer.output.layers import layer_channels, write_layers
        from viewer.output.render import render_to_files
        from viewer.scene.area_lights import AreaLights
        from viewer.scene.look import Look
        from viewer.scene.resampling import load_sized_scene

        times = {}
        t = time.perf_counter()
        key = (task["bundle"], task["max_size"], tuple(sorted(task["options"].items())))
        if key != self._engine_key:
            self._drop_engine()
            self._scene = load_sized_scene(task["bundle"], None, task["max_size"])
            self._engine = Engine(self.ctx, self._scene, EngineOptions(**task["options"]))
            self._engine_key = key
        times["scene"] = round(time.perf_counter() - t, 3)
        t = time.perf_counter()
        env = None
        if task.get("envmap"):
            if self._map[0] != task["envmap"]:
                self._map = (task["envmap"], load_envmap(task["envmap"]).pixels)
            env = self._map[1]
        lights = AreaLights.from_array(task["lights"])
        fixed = AreaLights.from_array(task["rig"]) if task.get("rig") is not None else None
        folder = Path(task["folder"])
        png = folder / task["outputs"][0]
        look = Look.from_json(task["look"])
        if task.get("plate"):  # the person put into a plate (its layers written with it)
            from viewer.output.plate_render import render_on_plate
            from viewer.plate.loader import read_plate
            from viewer.plate.placement import Placement, PlateSpot

            spot = PlateSpot(read_plate(task["plate"], []), Placement(*task["place"]), task["horizon"], task["bundle"],
                             task["cut_allowed"])
            render_on_plate(self._engine, self._scene, lights, look, spot, png, folder / task["outputs"][1],
                            folder / task["outputs"][2] if task.get("layers") else None, fixed=fixed)
            times["render"] = round(time.perf_counter() - t, 3)
            return {"times": times, "sha256": {rel: file_sha256(folder / rel) for rel in task["outputs"]}}
        render_to_files(self._engine, self._scene, lights, png.parent, png.stem, look, environment=env, passes=False,
                        fixed=fixed)
        times["render"] = round(time.perf_counter() - t, 3)
        if task.get("layers"):
            t = time.perf_counter()
            write_layers(folder / task["outputs"][2], layer_channels(self._engine, self._scene, task.get("per_light", False)))
            times["layers"] = round(time.perf_counter() - t, 3)
        return {"times": times, "sha256": {rel: file_sha256(folder / rel) for rel in task["outputs"]}}


def serve(threads: int, conn, parent: int) -> None:
    """A local worker process: tasks from its pipe, each result back on it, until a None task or
    its batch (process ``parent``) is gone: the kernel kills it with its parent (SIGKILL included),
    so nothing is written for a batch that is no longer there. Ctrl-C is the batch's to handle."""
    import signal

    die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if os.getppid() != parent:  # the parent went before the request took effect
        return
    worker = Worker(threads)
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        conn.send({**worker.run(task), "kind": "result", "id": task["id"]})
