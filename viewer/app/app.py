"""``relight view``: the interactive viewer. One loop on the window's thread: events, input, panel,
one engine render of the current state, draw, swap. Light fitting and video encoding run on their
own threads; GL stays on this one.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import time
from collections import deque
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from ..imageio import write_exr, write_png, write_text
from ..lightfit.methods import DEFAULT_METHOD
from ..placed_lights import PlacedLight, level
from ..lights import AreaLights, facing_yaw
from ..render import photo_exposure
from ..scene import PHOTO_SUFFIXES, Scene
from ..settings import AUTO, Look
from . import interaction as ix
from .jobs import ChildWorker, LightJob, SceneJob
from .layout import PANEL_WIDTH, image_area_size, panel_width
from .recording import InteractionRecording, TurntableRecording
from .session import Session

STILL_SECONDS = 0.25  # a drag that has not moved for this long renders at full quality
SWAP_BUDGET = 0.06  # seconds of engine work a frame gives a new map or person before the frame is shown
IDLE_WAIT = 0.25  # seconds the loop sleeps waiting for events when nothing is moving
JOB_WAIT = 0.1  # ... while lights are fitted on their thread (the job wakes the loop when it is done)
FRAME_HISTORY = 600
OPENS = (".hdr", ".exr", ".json", *PHOTO_SUFFIXES)  # what the window opens (and a bundle's folder)


@dataclass
class ViewerConfig:
    scene: Scene
    lights: AreaLights
    environment: np.ndarray | None
    env_path: Path | None
    method: str = DEFAULT_METHOD
    options: object = None  # EngineOptions
    look: Look = field(default_factory=Look)
    out_dir: Path = Path("relight-captures")
    record_frames: int = 120
    fps: float = 30.0
    state_file: Path | None = None  # state, widget positions and frame times as JSON (scripts, tests, benchmarks)
    bundled_maps: tuple = ()
    preset: str = "balanced"  # the quality preset the options came from (viewer/presets.py)
    window: object = None  # a window already open (a photo's inference ran in its context), else one is made
    rig: tuple = ()  # placed lights to start with (viewer.placed_lights; relight view --rig)
    max_size: int = 2048  # a photo or bundle opened in the window: its frame's longer side (relight view --max-size)
    device: str = "cpu"  # ... and where its inference runs (relight view --device)
    gl_threads: int = 2  # llvmpipe's threads (viewer/cores.py): with one, the drag preview is lighter


class ViewerApp:
    def __init__(self, config: ViewerConfig):
        from .files import FileBrowser
        from .thumbnail import MapThumbnail
        from .window import Window

        self.config = config
        sc = config.scene
        area_w, area_h = image_area_size(sc.output_size)
        if config.window is not None:
            self.window = config.window
            self.window.resize(area_w + PANEL_WIDTH, max(area_h, 860))
        else:
            self.window = Window(area_w + PANEL_WIDTH, max(area_h, 860), "relight")
        # "auto" exposure: the photo's own brightness, set from the first render (and again for each new map)
        self.auto_exposure = config.look.exposure == AUTO
        self._auto_value = 0.0  # the exposure auto set last: a user's change (wheel, slider) ends auto
        look = replace(config.look, exposure=0.0) if self.auto_exposure else config.look
        self.session = Session(self.window.ctx, sc, config.lights, config.environment, config.options, look,
                               light_preview=config.gl_threads < 2)
        self.session.set_placed(config.rig, record=False)
        self.session.wake = self.window.wake
        self.env_path = config.env_path
        self.n_lights = len(config.lights)
        self.preset = config.preset
        self.view = ix.ViewState()  # zoom and pan; the rotation and exposure are the session's look
        if self.auto_exposure:
            self._apply_auto_exposure()
        self.dragging = False
        self._drag_applied = (0.0, 0.0)  # drag motion already turned into rotation (pixels)
        self.panning = False
        self.last_motion = 0.0
        self.adjusted = 0.0  # when a panel widget was last held (its changes preview until it is let go)
        self.job: LightJob | None = None
        self.scene_job: SceneJob | None = None
        # the child processes that fit maps and infer photos, started on first use and kept (torch loads once)
        self.workers = {"lights": ChildWorker(), "photo": ChildWorker()}
        self.recording = None
        self.message = ""
        self.last_compare = 0.5  # where B puts the before / after split
        self.rig_choice = 0  # the rig the panel's combo shows
        self.aiming: int | None = None  # the placed light the next click on the person aims
        self.error = ""
        self.frames: deque = deque(maxlen=FRAME_HISTORY)  # (ms, kind)
        self._switched = False  # a finished job was applied (a new map's lights, a new person) and is not shown yet
        self._frame_start = time.perf_counter()
        self._expose_pending = False  # auto exposure to set from the next complete frame (_exposed_again)
        self.frame_count = 0
        self.widgets: dict = {}
        self.panel_height = 0.0  # the panel's content, drawn or not (the first frame fits the window to it)
        self.captures: list[str] = []
        self.videos: list[str] = []
        self._state_text = ""
        self._state_time = 0.0
        self._capture_index = 0
        self.thumbnail = MapThumbnail(self.window.ctx)
        self.browser = FileBrowser(config.env_path.parent if config.env_path else Path.cwd(), OPENS)
        self.show_browser = False

    def _apply_auto_exposure(self):
        """Exposure from the photo's own brightness under the current lights (a no-op, 0 stops,
        for a scene without a photo)."""
        s = self.session
        eng = s.render(preview=False)
        e = self._auto_value = photo_exposure(eng, s.scene, s.look.tonemap)
        s.update(exposure=e)

    # ------------------------------------------------------------------ geometry
    def image_area(self) -> tuple[float, float, float, float]:
        w, h = self.window.size
        return 0.0, 0.0, float(max(w - panel_width(w), 1)), float(max(h, 1))

    def image_rect(self) -> tuple[float, float, float, float]:
        _, _, aw, ah = self.image_area()
        sc = self.session.scene
        return ix.image_rect(sc.output_size, (aw, ah), self.view.zoom, self.view.pan)

    # ------------------------------------------------------------------ input
    def _input(self):
        from imgui_bundle import imgui

        io = imgui.get_io()
        mx, my = io.mouse_pos.x, io.mouse_pos.y
        ax, ay, aw, ah = self.image_area()
        over_image = ax <= mx < ax + aw and ay <= my < ay + ah and not io.want_capture_mouse
        recording_turn = self.replaying  # the lighting is the recording's, not the mouse's
        now = time.perf_counter()
        if self.aiming is not None and imgui.is_mouse_clicked(0) and over_image:
            self.aim_at(mx - ax, my - ay)
        elif imgui.is_mouse_clicked(0) and over_image and not recording_turn:
            self.dragging = True
            self._drag_applied = (0.0, 0.0)
        if self.dragging:
            # motion since the press, from imgui's own press position: nothing is lost between
            # the press and the first frame that sees it, nor before the release
            down = imgui.is_mouse_down(0)
            if down or imgui.is_mouse_released(0):
                total = imgui.get_mouse_drag_delta(0, 0.0)
                dx, dy = total.x - self._drag_applied[0], total.y - self._drag_applied[1]
                if dx or dy:
                    self.session.look = ix.dragged(self.session.look, dx, dy)
                    self._drag_applied = (total.x, total.y)
                    self.last_motion = now
            if not down:
                self.dragging = False
        if imgui.is_mouse_clicked(1) and over_image:
            self.panning = True
        elif self.panning:
            if imgui.is_mouse_down(1):
                self.view = ix.panned(self.view, io.mouse_delta.x, io.mouse_delta.y)
            else:
                self.panning = False
        if over_image and io.mouse_wheel:
            if io.key_ctrl:
                self.view = ix.zoomed(self.view, io.mouse_wheel, cursor=(mx - ax, my - ay), area=(aw, ah))
            else:
                self.session.look = ix.wheeled(self.session.look, io.mouse_wheel)
        shortcuts = self.window.take_shortcuts()
        if io.want_capture_keyboard:
            return
        if imgui.is_key_pressed(imgui.Key.s, False):
            self.save_frame()
        if imgui.is_key_pressed(imgui.Key.r, False):
            self.toggle_recording("live")
        if imgui.is_key_pressed(imgui.Key.t, False):
            self.toggle_recording("turntable")
        if imgui.is_key_pressed(imgui.Key.f, False):
            self.view = replace(self.view, zoom=1.0, pan=(0.0, 0.0))
        if imgui.is_key_pressed(imgui.Key._0, False):
            self.session.update(yaw=0.0, tilt=0.0)
        if imgui.is_key_pressed(imgui.Key.b, False):
            self.toggle_compare()
        if imgui.is_key_pressed(imgui.Key.g, False):
            self.session.update(ground=not self.session.ground_shown)
        for key in shortcuts:
            if key == "undo":
                self.message = "undone" if self.session.undo() else "nothing to undo"
            else:
                self.message = "redone" if self.session.redo() else "nothing to redo"
        if imgui.is_key_pressed(imgui.Key.q, False) or imgui.is_key_pressed(imgui.Key.escape, False):
            self.window.close()

    # ------------------------------------------------------------------ actions
    def _capture_stem(self) -> Path:
        self._capture_index += 1
        stamp = time.strftime("%Y%m%d-%H%M%S")
        return self.config.out_dir / f"relight-{stamp}-{self._capture_index:03d}"

    def _report(self, what: str, exc: Exception):
        """An error in an action: shown in the panel and printed; the viewer goes on."""
        self.error = f"{what}: {exc}"
        print(f"relight: error: {self.error}", file=sys.stderr, flush=True)

    def save_frame(self):
        try:
            self._save_frame()
        except Exception as exc:  # an unwritable folder, a full disk: reported, the viewer goes on
            self._report("saving the frame failed", exc)

    def _save_frame(self):
        """The current state at full quality: display PNG, HDR EXR and a JSON of lights and look."""
        eng = self.session.render(preview=False)
        stem = self._capture_stem()
        png = write_png(stem.with_suffix(".png"), eng.read_display().astype(np.float32) / 255.0)
        write_exr(stem.with_suffix(".exr"), eng.read_output_hdr()[..., :3])
        state = {"look": self._look_json(), "map": str(self.env_path) if self.env_path else None, "preset": self.preset}
        state["lights"] = self.session.rendered_lights().to_json()  # what was rendered: the map's and the placed
        state["rig"] = [asdict(p) for p in self.session.placed]
        write_text(stem.with_suffix(".json"), json.dumps(state, indent=2) + "\n")
        self.captures.append(str(png))
        self.message = f"saved {png.name} (+ .exr, .json)"
        print(f"saved {png} {stem.with_suffix('.exr')} {stem.with_suffix('.json')}", flush=True)

    @property
    def replaying(self) -> bool:
        """Whether the recording, not the user, sets the lighting now: a turn, or a captured
        interaction being rendered."""
        rec = self.recording
        return isinstance(rec, TurntableRecording) or (isinstance(rec, InteractionRecording) and not rec.capturing)

    def toggle_recording(self, kind: str):
        rec = self.recording
        if isinstance(rec, InteractionRecording) and rec.capturing:
            rec.stop(self.session.look, self.session.placed, self.session.sigma)  # the capture ends: its frames are rendered from the next pass on
            self.message = f"rendering {rec.total} frames of {rec.path.name}"
            return
        if rec is not None:
            self._finish_recording(stopped=True)
            return
        size = self.session.scene.output_size
        path = self._capture_stem().with_suffix(".mp4")
        try:
            if kind == "turntable":
                self.recording = TurntableRecording(path, size, self.session.look.yaw, self.config.record_frames, self.config.fps)
            else:
                self.recording = InteractionRecording(path, size, self.config.fps)
        except Exception as exc:
            self._report(f"cannot record to {path}", exc)
            return
        self.message = f"recording {path.name}"

    def _apply_moment(self, m):
        s = self.session
        s.look = m.look.fitted(len(s.base_lights) + len(m.placed))
        s.set_placed(m.placed, record=False)
        if len(m.sigma) == len(s.sigma):  # the same map's lights (a refit meanwhile keeps the new sigmas)
            s.sigma[:] = m.sigma

    def _render_capture(self, rec: InteractionRecording):
        """A quit during a capture: its frames rendered now (nothing else holds what the user did)."""
        rec.stop(self.session.look, self.session.placed, self.session.sigma)
        print(f"rendering the {rec.total} frames of {rec.path.name} before quitting", flush=True)
        while not rec.finished:
            self._apply_moment(rec.moment(rec.done))
            self.session.render()
            rec.add(self.session.final.read_display())

    def _finish_recording(self, stopped: bool = False):
        rec, self.recording = self.recording, None
        if isinstance(rec, TurntableRecording):
            self.session.update(yaw=rec.start_yaw)
        if isinstance(rec, InteractionRecording):
            try:
                if rec.capturing:
                    self._render_capture(rec)
            finally:
                self._apply_moment(rec.resume)  # back to where the user was
        try:
            path = rec.close()
        except Exception as exc:
            self._report(f"recording {rec.path} failed", exc)
            return
        how = "stopped after" if stopped and not rec.finished else "recorded"
        self.videos.append(str(path))
        self.message = f"{how} {rec.done} frames: {path.name}"
        print(f"{how} {rec.done} frames to {path}", flush=True)

    def open_map(self, path: Path, n: int | None = None):
        if self.job is not None:
            self.message = "still fitting the previous map"
            return
        self.error = ""
        self.message = f"lights for {Path(path).name}; the window stays live meanwhile"
        self.job = LightJob(path, n or self.n_lights, self.config.method, wake=self.window.wake,
                            worker=self.workers["lights"])

    def open_scene(self, path: Path):
        """Another person: a photo (inferred in a child process, or from the cache) or a scene
        bundle, read on a thread; the window shows it when its maps are ready (:meth:`_poll_scene_job`)."""
        if self.scene_job is not None:
            self.message = f"still opening {self.scene_job.path.name}"
            return
        self.error = ""
        self.message = f"opening {path.name}; the window stays live meanwhile"
        self.scene_job = SceneJob(path, self.config.max_size, self.config.device, wake=self.window.wake,
                                  worker=self.workers["photo"])

    def open_file(self, path: Path):
        """A file dropped on the window or chosen in its browser: a photo or a scene bundle (its
        folder or its scene.json) becomes the person shown; an environment map is fitted and
        switched to with its lights; a rig's lights are placed. Anything else is one line saying
        what the window opens."""
        from ..errors import InputError
        from ..file_kinds import kind_of, wrong_kind
        from ..placed_lights import load_rig
        from .files import is_bundle

        suffix = path.suffix.lower()
        if is_bundle(path):
            self.open_scene(path)
        elif path.name == "scene.json":
            self.open_scene(path.parent)
        elif suffix in PHOTO_SUFFIXES:
            self.open_scene(path)
        elif suffix in (".hdr", ".exr"):
            self.open_map(path)
        elif suffix == ".json" and kind_of(path) not in ("rig", None):  # a light file, a saved look...
            self.error = str(wrong_kind(path, "a rig"))
        elif suffix == ".json":
            try:
                self.session.set_placed(load_rig(path))
            except InputError as exc:
                self.error = str(exc)
                return
            self.message = f"{len(self.session.placed)} placed lights from {path.name}"
        else:
            self.error = (f"{path}: the window opens photos ({', '.join(PHOTO_SUFFIXES)}), scene bundles (a folder "
                          "with scene.json), environment maps (.hdr, .exr) and rigs (.json)")

    def aim_at(self, x: float, y: float):
        """Aim the placed light being aimed so that it faces the person's surface under the image
        point (x, y) head-on (its direction: the normal there)."""
        sc = self.session.scene
        px = ix.image_pixel((x, y), self.image_rect(), (sc.width, sc.height))
        if px is None or not sc.mask[px[1], px[0]]:
            self.aiming = None
            self.message = "not aimed: click on the person"
            return
        self.aim_direction(sc.normal[px[1], px[0]], f"the person's pixel {px[0]}, {px[1]}")

    def aim_direction(self, direction, where: str = "the map's point clicked"):
        """The placed light being aimed turned to come from ``direction`` (camera space); with none
        being aimed, a new light from there."""
        s = self.session
        j, self.aiming = self.aiming, None
        placed = list(s.placed)
        if j is None or j >= len(placed):
            placed.append(PlacedLight.aimed(direction, intensity=self.placed_level()))
            j, verb = len(placed) - 1, "added at"
        else:
            p = placed[j]
            placed[j] = PlacedLight.aimed(direction, size=p.size, intensity=p.intensity, kelvin=p.kelvin)
            verb = "aimed at"
        s.set_placed(placed)
        self.message = f"light {len(s.base_lights) + j} {verb} {where}"

    def placed_level(self) -> float:
        """A new placed light's intensity: the map's level (viewer.placed_lights.level)."""
        return level(self.session.base_lights)

    def save_rig(self):
        from ..placed_lights import save_rig

        try:
            self.config.out_dir.mkdir(parents=True, exist_ok=True)
            path = save_rig(self._capture_stem().with_name(f"rig-{time.strftime('%Y%m%d-%H%M%S')}.json"),
                            self.session.placed)
        except OSError as exc:
            self._report("saving the rig failed", exc)
            return
        self.message = f"saved the rig: {path.name} (relight view --rig {path.name})"

    def toggle_compare(self):
        """Before / after: the original photo left of a split (at the last position, half the frame
        at first), or the relit frame alone again."""
        if self.session.scene.frame is None:
            self.message = "before / after needs a photo: this scene has no original to show"
            return
        look = self.session.look
        if look.compare > 0.0:
            self.last_compare = look.compare
        self.session.update(compare=0.0 if look.compare > 0.0 else self.last_compare)

    def set_preset(self, name: str):
        """A quality preset: its engine options now, its number of lights refitted (cached) when the
        lights came from a map."""
        from ..presets import preset

        p = preset(name)
        self.preset = name
        self.session.set_options(p.options)
        if p.lights != len(self.session.sigma) and self.env_path is not None:
            self.n_lights = p.lights
            self.open_map(self.env_path, p.lights)
        self.message = f"preset {name}: {p.summary}"

    def _finished(self, attr: str):
        """The job in ``self.<attr>`` once it has ended (the attribute emptied): its result, or None
        (still running, none, or failed: its error shown and printed)."""
        job = getattr(self, attr)
        if job is None or not job.done:
            return None
        setattr(self, attr, None)
        if job.error:
            self.error, self.message = job.error, ""
            print(f"relight: error: {job.error}", file=sys.stderr, flush=True)
            return None
        self._switched = True
        return job

    def _exposed_again(self):
        """After new lights or a new person: auto exposure, unless the user has set one since, set
        from the new state's first complete frame (:meth:`_render`), before it is shown."""
        self._expose_pending = self.auto_exposure and self.session.look.exposure == self._auto_value

    def _poll_scene_job(self):
        job = self._finished("scene_job")
        if job is None:
            return
        res = job.result
        self.session.set_scene(res.scene)
        self.session.update(yaw=facing_yaw(self.session.lights))  # its first frame faces the brightest light
        self.view = ix.ViewState()
        self._exposed_again()
        self.window.set_title(f"relight - {res.path.name}")
        how = {"inferred": "inferred now, cached for next time", "cached": "its bundle from the cache",
               "bundle": "a scene bundle"}[res.how]
        self.message = f"opened {res.path.name} ({how}): {res.scene.output_size[0]}x{res.scene.output_size[1]}"
        print(self.message, flush=True)

    def _poll_job(self):
        job = self._finished("job")
        if job is None:
            return
        res = job.result
        new_map = job.path != self.env_path
        self.session.set_lights(res.lights, environment=res.env.pixels, new_map=new_map)
        if new_map:  # as the first map: its brightest light on the camera's side
            self.session.update(yaw=facing_yaw(res.lights))
        self.env_path = job.path
        self.n_lights = len(res.lights)
        self._exposed_again()
        self.message = f"{len(res.lights)} lights ({res.how}) for {job.path.name}"
        print(self.message, flush=True)

    def _fit_panel(self):
        """A window taller than the panel's content where the screen has room: nothing is cut off
        and no scrolling is needed at first (a smaller screen keeps the panel's scroll bar)."""
        w, h = self.window.size
        need = int(np.ceil(self.panel_height))
        screen = self.window.screen_height()
        if need > h and screen is not None:
            self.window.resize(w, min(need, max(screen - 40, h)))

    # ------------------------------------------------------------------ frame
    def _render(self) -> tuple[object, str]:
        """Render the current state; returns the engine to show and what kind of frame it was."""
        s = self.session
        rec = self.recording
        if isinstance(rec, TurntableRecording):
            s.update(yaw=rec.next_yaw())
        if isinstance(rec, InteractionRecording):
            if rec.capturing:
                rec.capture(s.look, s.placed, s.sigma)
            else:
                self._apply_moment(rec.moment(rec.done))
        capturing = isinstance(rec, InteractionRecording) and rec.capturing
        now = time.perf_counter()
        moving = self.dragging and now - self.last_motion < STILL_SECONDS
        adjusting = not moving and now - self.adjusted < STILL_SECONDS  # a panel slider held: soft shadows kept
        switching = self._switched and rec is None  # a new map or person: brought in over frames of SWAP_BUDGET
        preview = (moving or adjusting) and (rec is None or capturing) and not switching
        rendered = s.preview if preview else s.final
        before = sum(rendered.counters.values())
        budget = max(SWAP_BUDGET - (now - self._frame_start), 0.0) if switching else None  # what the frame has left
        expose = switching and self._expose_pending  # auto exposure from the new HDR, before its frame is drawn
        eng = s.render(preview=preview, hard=moving, budget=budget, display=not expose)
        worked = sum(rendered.counters.values()) != before
        if expose and rendered.composited:
            self._expose_pending = False
            e = self._auto_value = photo_exposure(rendered, s.scene, s.look.tonemap)
            s.update(exposure=e)
            return eng, "load"  # the next pass draws the frame at that exposure
        if switching and not rendered.complete:
            return eng, "load"  # the last complete frame stays on screen while the rest is done
        if rec is not None and not capturing:
            try:
                rec.add(eng.read_display())
            except Exception as exc:
                self._report(f"recording {rec.path} failed", exc)
                self.recording = None
                if isinstance(rec, TurntableRecording):
                    s.update(yaw=rec.start_yaw)  # the lighting goes back to where the turn started
                else:
                    self._apply_moment(rec.resume)
                try:
                    rec.close()  # releases the file; its error is the one just reported
                except Exception:
                    pass
                return eng, "record"
            if rec.finished:
                self._finish_recording()
            return eng, "record"
        if self._switched:  # "switch": the frame that shows what a job loaded (its work may be done before _render)
            self._switched = False
            if self._expose_pending:  # switched while recording, at full quality: exposed from the next frame on
                self._expose_pending = False
                self._apply_auto_exposure()
            return eng, "switch"
        if not worked:  # "load": nothing to redraw while lights are fitted or a scene opened off this thread
            if self.job is not None or self.scene_job is not None:
                return eng, "load"
            # "warm": an idle frame makes the drag preview's engine, so the first dragged frame is a preview's
            return eng, "warm" if s.warm_preview() else "idle"
        return eng, ("drag" if moving else "adjust") if preview else "update"

    def run(self) -> int:
        from .panel import draw_panel

        w = self.window
        previous = signal.signal(signal.SIGTERM, lambda *_: w.close()) if os.name == "posix" else None
        try:
            while not w.should_close:
                # a slider let go: the loop runs on until its full-quality frame replaces the preview
                busy = (self.dragging or self.panning or self.recording is not None
                        or time.perf_counter() - self.adjusted < 2 * STILL_SECONDS)
                waiting = self.job is not None or self.scene_job is not None or self.session.refining
                w.wait(None if busy else (JOB_WAIT if waiting else IDLE_WAIT))
                start = self._frame_start = time.perf_counter()
                w.begin_frame()
                self._input()
                for path in w.take_dropped():
                    self.open_file(Path(path))
                draw_panel(self)
                if self.frame_count == 0:
                    self._fit_panel()
                self._poll_job()
                self._poll_scene_job()
                self.session.poll_refinement()
                eng, kind = self._render()
                w.draw_image(eng.display, self.image_rect(), self.image_area())
                w.end_frame()
                self.frames.append(((time.perf_counter() - start) * 1000.0, kind))
                self.frame_count += 1
                self._write_state()
        finally:
            try:
                if self.recording is not None:
                    self._finish_recording(stopped=True)
                self._write_state(force=True)
            finally:
                for job in (self.job, self.scene_job):
                    if job is not None:
                        job.stop()  # a fit or an inference ends at once (its child is killed)
                for worker in self.workers.values():
                    worker.close()
                self.session.release()
                self.thumbnail.release()
                w.release()
            if previous is not None:
                signal.signal(signal.SIGTERM, previous)
        return 0

    # ------------------------------------------------------------------ state file
    def _look_json(self) -> dict:
        return replace(self.session.look, preset=self.preset).to_json()

    def _write_state(self, force: bool = False):
        path = self.config.state_file
        if path is None:
            return
        rec = self.recording
        state = {
            "look": self._look_json(),
            "sigma": [float(v) for v in self.session.sigma],
            "placed": [asdict(p) for p in self.session.placed],
            "n_lights": len(self.session.sigma),
            "preset": self.preset,
            "map": str(self.env_path) if self.env_path else None,
            "image_rect": list(self.image_rect()),
            "window_size": list(self.window.size),
            "panel_height": self.panel_height,
            "widgets": self.widgets,
            "recording": None if rec is None else {"kind": rec.kind, "frames": rec.done, "total": rec.total, "path": str(rec.path),
                                                   "capturing": getattr(rec, "capturing", False),
                                                   "seconds": getattr(rec, "seconds", None)},
            "fitting": self.job is not None,
            "opening": None if self.scene_job is None else str(self.scene_job.path),
            "scene_size": list(self.session.scene.output_size),
            "refined": self.session.final.refined_current,
            "refine_error": self.session.refine_error,
            "captures": self.captures,
            "videos": self.videos,
            "message": self.message,
            "error": self.error,
            "gl_threads": self.config.gl_threads,  # llvmpipe's, sized when the window opened (viewer/cores.py)
        }
        text = json.dumps(state)
        now = time.monotonic()
        if text == self._state_text and not force and now - self._state_time < 1.0:  # frame times: once a second
            return
        self._state_text, self._state_time = text, now
        state["frame_count"] = self.frame_count
        state["frames"] = [[round(ms, 3), kind] for ms, kind in self.frames]
        write_text(path, json.dumps(state))


def run_viewer(config: ViewerConfig) -> int:
    # background work runs on threads (reading a scene's maps, the refinement network; light fits and
    # a photo's inference run in child processes, their threads only read them): hand the GIL over
    # every 0.5 ms, not 5, so a frame of the window waits little behind the work's Python steps;
    # the interpreter's own interval is back when the window closes
    previous = sys.getswitchinterval()
    sys.setswitchinterval(0.0005)
    try:
        return ViewerApp(config).run()
    finally:
        sys.setswitchinterval(previous)
