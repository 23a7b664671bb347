"""Work off the window's thread: opening a photo or a scene bundle (a photo's inference in a child
process, :mod:`viewer.app.child`; the window shows the new scene when its maps are read), light
fitting (in a child process too: the window keeps drawing, with a progress bar, while a map's
lights are fitted, then swaps in the new map and its lights together) and the shadow
refinement network (run on the visibility the engine read back; its result is used only if the
lights have not moved since)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from viewer.app.thumbnail import map_thumbnail
from viewer.errors import InputError
from viewer.lighting.envmap import EnvMap, load_envmap
from viewer.lighting.map_lights import map_lights
from viewer.scene.area_lights import AreaLights


@dataclass
class LightsResult:
    env: EnvMap
    lights: AreaLights
    how: str  # "bundled", "cached" or "fitted"
    thumbnail: np.ndarray  # the panel's picture of the map (viewer.app.thumbnail), made on the job's thread


class Cancelled(Exception):
    """Raised inside a job's work when :meth:`ThreadJob.stop` asked it to end."""


class ThreadJob(ABC):
    """Work on a daemon thread: ``result`` when :meth:`work` returns, ``error`` (one line, from
    :meth:`failure`) when it raises; ``wake()`` is called when it finishes (to wake the window's
    event wait). Subclasses set their own fields, then call ``super().__init__``, which starts it.
    :meth:`stop` ends a job early: its work checks :meth:`check_cancelled` between steps (a daemon
    thread still inside torch when the program exits aborts the process)."""

    thread_name = "job"

    def __init__(self, wake=lambda: None):
        self.result = None
        self.error: str | None = None
        self._wake = wake
        self._cancel = threading.Event()
        self._thread = threading.Thread(target=self._run, name=self.thread_name, daemon=True)
        self._thread.start()

    @property
    def done(self) -> bool:
        return not self._thread.is_alive()

    def check_cancelled(self):
        if self._cancel.is_set():
            raise Cancelled()

    def stop(self, timeout: float = 60.0) -> bool:
        """Ask the work to end at its next step and wait for it; True once the thread has ended."""
        self._cancel.set()
        self._thread.join(timeout)
        return self.done

    @abstractmethod
    def work(self):
        """The job's work, on the thread; its return value becomes ``result``."""

    @abstractmethod
    def failure(self, exc: Exception) -> str:
        """The one-line ``error`` for an exception ``work`` raised."""

    def _run(self):
        try:
            self.result = self.work()
        except Cancelled:
            pass
        except Exception as exc:  # shown in the panel; the window keeps what it had
            self.error = self.failure(exc)
        finally:
            self._wake()


class ChildWorker:
    """One long-lived child process (:mod:`viewer.app.child`), started on the first request (or ahead
    of it, :meth:`start`) and kept for the next ones (torch is imported once); one request at a time. :meth:`kill` ends a
    request at once (the next request starts a new child); :meth:`close` ends the child."""

    def __init__(self):
        self._proc: subprocess.Popen | None = None
        self._lock = threading.Lock()

    def start(self):
        """Start the child now if none is running (the window, when its file browser opens, so that the
        map chosen next does not wait for its start: ~1.5 s of importing torch on this machine). Never
        waits: a request under way holds the lock, and its child is running."""
        if not self._lock.acquire(blocking=False):
            return
        try:
            if self._proc is None or self._proc.poll() is not None:
                self._start()
        finally:
            self._lock.release()

    def _start(self) -> subprocess.Popen:
        self._close_pipes()  # of a child that died, if any
        root = str(Path(__file__).resolve().parents[2])  # the package's parent: found whatever the current folder
        env = dict(os.environ)
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        self._proc = subprocess.Popen([sys.executable, "-m", "viewer.app.child"], stdin=subprocess.PIPE,
                                      stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env)
        return self._proc

    @staticmethod
    def _send(proc: subprocess.Popen, req: dict):
        proc.stdin.write(json.dumps(req) + "\n")
        proc.stdin.flush()

    def request(self, req: dict, source, on_stage, check_cancelled) -> dict:
        """Send ``req``; ``on_stage(message)`` for each progress line; returns the result line;
        raises InputError with the error line (or naming ``source`` when the child died)."""
        with self._lock:
            proc = self._proc if self._proc is not None and self._proc.poll() is None else self._start()
            try:
                self._send(proc, req)
            except OSError:  # it died between requests: once more with a new one
                proc = self._start()
                self._send(proc, req)
            for line in proc.stdout:
                check_cancelled()
                try:
                    msg = json.loads(line)
                except json.JSONDecodeError:
                    continue  # a library's own print
                if not isinstance(msg, dict):
                    continue
                if "stage" in msg:
                    on_stage(msg)
                elif "error" in msg:
                    raise InputError(None, str(msg["error"]))  # already names the file
                else:
                    return msg
            check_cancelled()
            code = proc.wait()
            self._close_pipes(proc)
            self._proc = None
            raise InputError(source, f"the work ended without a result (exit status {code})")

    def kill(self):
        proc = self._proc
        if proc is not None and proc.poll() is None:
            proc.kill()  # what it writes (a bundle, a cache entry) appears whole or not at all

    def close(self):
        """End the child at once: between requests it holds nothing unwritten (what it writes appears
        whole or not at all), and letting torch's interpreter wind down cost most of a second of the
        window's exit."""
        proc = self._proc
        self._proc = None
        if proc is None:
            return
        proc.kill()
        proc.wait()
        self._close_pipes(proc)

    def _close_pipes(self, proc: subprocess.Popen | None = None):
        proc = proc or self._proc
        if proc is None:
            return
        for stream in (proc.stdin, proc.stdout):
            try:
                stream.close()
            except OSError:
                pass


class ChildJob(ThreadJob):
    """A job whose heavy part is a request to a :class:`ChildWorker` (the window's, kept between
    jobs; without one, a worker of its own, closed when the job ends), read on the job's thread;
    :meth:`stop` ends the request at once."""

    def __init__(self, wake=lambda: None, worker: ChildWorker | None = None):
        self._own = worker is None
        self.worker = worker if worker is not None else ChildWorker()
        super().__init__(wake)

    def _run(self):
        try:
            super()._run()
        finally:
            if self._own:
                self.worker.close()

    def stop(self, timeout: float = 60.0) -> bool:
        if not self.done:
            self._cancel.set()
            self.worker.kill()
        return super().stop(timeout)

    def run_child(self, req: dict, source, on_stage) -> dict:
        return self.worker.request(req, source, on_stage, self.check_cancelled)

    def failure(self, exc: Exception) -> str:
        return str(exc) if isinstance(exc, InputError) else f"{self.path}: {type(exc).__name__}: {exc}"


class LightJob(ChildJob):
    """Load ``path`` and get its ``n`` lights (beside the map, from the cache, or fitted in a child
    process) on a thread; ``result`` is a :class:`LightsResult`."""

    thread_name = "light-fit"

    def __init__(self, path, n: int, method: str, wake=lambda: None, worker: ChildWorker | None = None):
        self.path = Path(path)
        self.n = n
        self.method = method
        self.stage = "loading the map"
        self.fraction = 0.0
        self._left = None  # the fit's time left, from its first step
        super().__init__(wake, worker)

    def _stage(self, said: dict):
        from viewer.lighting.lightfit.methods import STAGE_SHARES
        from viewer.progress import TimeLeft

        if self._left is None:
            self._left = TimeLeft(STAGE_SHARES.get(self.method) or {str(said["stage"]): 1.0})
        self.fraction = self._left.update(str(said["stage"]), int(said.get("done", 0)), int(said.get("total", 1)))
        words = self._left.words()
        self.stage = str(said["stage"]) + (f": {words}" if words else "")

    def work(self) -> LightsResult:
        env = load_envmap(self.path)
        lights, how = map_lights(env, self.path, self.n, self.method, self._fit_in_child)
        # made here, not in the frame that shows the map: its first one imported scipy, 0.16 s of that frame
        return LightsResult(env, lights, how, map_thumbnail(env))

    def _fit_in_child(self, env) -> tuple[AreaLights, bool]:
        self.stage = "fitting"
        said = self.run_child({"what": "lights", "map": str(self.path), "n": self.n, "method": self.method}, self.path,
                              self._stage)
        return AreaLights.from_array(np.asarray(said["lights"], dtype=np.float32)).validate(self.path), bool(said.get("cached"))


@dataclass
class SceneResult:
    scene: object  # viewer.scene.bundle.Scene
    path: Path  # what was opened: a photo or a bundle
    how: str  # "inferred", "cached" or "bundle"


class SceneJob(ChildJob):
    """Open a photo (its bundle inferred in a niced child process, or found in the cache) or a scene
    bundle, and read its maps (``max_size``: the frame's longer side, as ``relight view
    --max-size``); ``result`` is a :class:`SceneResult`."""

    thread_name = "open-scene"

    def __init__(self, path, max_size: int, device: str = "cpu", wake=lambda: None, worker: ChildWorker | None = None):
        from viewer.scene.bundle import PHOTO_SUFFIXES

        self.path = Path(path)
        self.photo = self.path.suffix.lower() in PHOTO_SUFFIXES
        self.max_size = max_size
        self.device = device
        self.stage = "starting the inference" if self.photo else "reading the maps"
        self.fraction = 0.0
        self._done = 0
        from viewer.photo.inference import STAGE_SHARES
        from viewer.progress import TimeLeft

        self._left = TimeLeft(STAGE_SHARES)
        super().__init__(wake, worker)

    def _stage(self, said: dict):
        from viewer.photo.inference import STAGES

        self._done += 1
        self.fraction = self._left.update(str(said["stage"]), 1, 1)
        words = self._left.words()
        self.stage = f"{said['stage']} done ({self._done} of {len(STAGES)})" + (f", {words}" if words else "")

    def work(self) -> SceneResult:
        from viewer.scene.resampling import load_sized_scene

        bundle, how = self.path, "bundle"
        if self.photo:
            said = self.run_child({"what": "photo", "photo": str(self.path), "max_size": self.max_size,
                                   "device": self.device}, self.path, self._stage)
            bundle, how = Path(said["bundle"]), "cached" if said.get("cached") else "inferred"
            self.stage = "reading the maps"
        scene = load_sized_scene(bundle, None, self.max_size)
        if scene.frame is not None:  # packed here (cached properties), not in the frame that shows the person
            _ = scene.frame.texels, scene.frame.box
        return SceneResult(scene, self.path, how)


class RefineJob(ThreadJob):
    """The refinement network on one lighting's (hard, soft) visibility, on a thread. ``key`` names
    the lighting it belongs to."""

    thread_name = "shadow-refinement"

    def __init__(self, refiner, hard, soft, sigma, depth, mask, key, wake=lambda: None):
        self.key = key
        self._args = (hard, soft, sigma, depth, mask)
        self._refiner = refiner
        super().__init__(wake)

    def work(self):
        return self._refiner(*self._args, cancelled=self.check_cancelled)

    def failure(self, exc: Exception) -> str:
        return f"shadow refinement failed: {type(exc).__name__}: {exc}"


class SaveJob(ThreadJob):
    """A saved frame's files written on a thread (the pixels read from GL before): the display PNG,
    the HDR EXR and the JSON of lights and look, each written atomically; ``result`` is the PNG's path."""

    thread_name = "save"

    def __init__(self, stem: Path, display: np.ndarray, hdr: np.ndarray, state_json: str, wake=lambda: None):
        self.stem, self.display, self.hdr, self.state_json = stem, display, hdr, state_json
        super().__init__(wake)

    def work(self) -> Path:
        from viewer.files.imageio import write_exr, write_png, write_text

        png = write_png(self.stem.with_suffix(".png"), self.display.astype(np.float32) / 255.0)
        write_exr(self.stem.with_suffix(".exr"), self.hdr)
        write_text(self.stem.with_suffix(".json"), self.state_json)
        return png

    def failure(self, exc: Exception) -> str:
        return f"saving {self.stem.name} failed: {exc}"


class PlateSaveJob(SaveJob):
    """A frame saved on a plate: the person (read from GL before) composited into the whole plate and
    written on a thread (:func:`viewer.output.plate_render.write_on_plate`: the PNG, its EXR with the
    person, shadow and plate layers, as ``relight render --plate --layers``), and the JSON."""

    def __init__(self, stem: Path, frame: tuple, plate, place, horizon: float, state_json: str, wake=lambda: None, anchor=None):
        self.frame, self.plate, self.place, self.horizon, self.anchor = frame, plate, place, horizon, anchor
        super().__init__(stem, None, None, state_json, wake)

    def work(self) -> Path:
        from viewer.files.imageio import write_text
        from viewer.output.plate_render import write_on_plate
        from viewer.plate.placement import PlateSpot

        png = self.stem.with_suffix(".png")
        spot = PlateSpot(self.plate, self.place, self.horizon, cut_allowed=True)
        write_on_plate(self.frame, spot, png, self.stem.with_suffix(".exr"), layers_in_exr=True, anchor=self.anchor)
        write_text(self.stem.with_suffix(".json"), self.state_json)
        return png
