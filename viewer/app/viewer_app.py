"""``relight view``: the interactive viewer. One loop on the window's thread: events, input, one
engine render of the current state, the panel (of the picture drawn), draw, swap. Light fitting and
video encoding run on their own threads; GL stays on this one.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from viewer.app import interaction as ix
from viewer.app.actions import Actions
from viewer.app.clip_player import ClipPlayer
from viewer.app.controls import Controls
from viewer.app.frame_log import FrameLog
from viewer.app.frame_plan import FramePlan
from viewer.app.job_polling import JobPolling
from viewer.app.jobs import ChildWorker, LightJob, SceneJob
from viewer.app.layout import PANEL_WIDTH, image_area_size, panel_width
from viewer.app.panel_state import PanelState
from viewer.app.preview import STILL_SECONDS, PreviewPace
from viewer.app.recorder import Recorder
from viewer.app.recording import ClipRecording, InteractionRecording, TurntableRecording
from viewer.app.session import Session
from viewer.app.state_file import StateFile
from viewer.gl import Engine
from viewer.lighting.lightfit.methods import DEFAULT_METHOD
from viewer.scene.area_lights import AreaLights
from viewer.scene.bundle import PHOTO_SUFFIXES, Scene
from viewer.scene.look import AUTO, Look

IDLE_WAIT = 0.25  # seconds the loop sleeps waiting for events when nothing is moving
JOB_WAIT = 0.1  # ... while lights are fitted on their thread (the job wakes the loop when it is done)
OPENS = (".hdr", ".exr", ".json", *PHOTO_SUFFIXES)  # what the window opens (and a bundle's folder)


@dataclass(frozen=True)
class HeldLighting:
    """The lighting of the picture on screen, as the panel shows it while a new map or person comes in."""
    look: Look
    sigma: np.ndarray
    lights: AreaLights  # turned by the look, as the lights' list shows them
    ground: bool  # whether the ground shadow shows


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
    preset: str = "balanced"  # the quality preset the options came from (viewer/gl/presets.py)
    window: object = None  # a window already open (a photo's inference ran in its context), else one is made
    rig: tuple = ()  # placed lights to start with (viewer.lighting.placed_lights; relight view --rig)
    max_size: int = 2048  # a photo or bundle opened in the window: its frame's longer side (relight view --max-size)
    device: str = "cpu"  # ... and where its inference runs (relight view --device)
    gl_threads: int = 2  # llvmpipe's threads, as main sized them (the cores it may use): reported in the state file
    clip: object = None  # a clip bundle (viewer.scene.clip_bundle.ClipBundle) played with a timeline; scene is its first frame's
    size: int | None = None  # the maps' size its frames are read at (relight view --size)
    plate: tuple | None = None  # the person put into a plate (--plate): viewer.app.plate_view.PlateView's arguments
    plate_notes: tuple = ()  # what reading and placing the plate said (shown in its panel section)
    lights_count: int = 16  # how many lights a map opened in the window is fitted with (-n, else the preset's)


class ViewerApp:
    def __init__(self, config: ViewerConfig):
        from viewer.app.files import FileBrowser
        from viewer.app.thumbnail import MapThumbnail
        from viewer.app.window import Window

        self.config = config
        self.clip = ClipPlayer(self)  # a clip's frames in the window
        self.frames = FramePlan(self)  # what is drawn next, and the automatic exposure
        sc = config.scene
        shown_size = sc.output_size if config.plate is None else config.plate[0].size
        area_w, area_h = image_area_size(shown_size)
        if config.window is not None:
            self.window = config.window
            self.window.resize(area_w + PANEL_WIDTH, max(area_h, 860))
        else:
            self.window = Window(area_w + PANEL_WIDTH, max(area_h, 860), "relight")
        # "auto" exposure: the photo's own brightness, set from the first render (and again for each new map)
        self.auto_exposure = config.look.exposure == AUTO
        self.auto_value = 0.0  # the exposure auto set last: a user's change (wheel, slider) ends auto
        look = replace(config.look, exposure=0.0) if self.auto_exposure else config.look
        self.timeline = None  # a clip's (viewer/app/timeline.py): the frame shown, playing or paused
        self.relit = None  # its relit pictures, prepared while the window is idle (viewer/app/relit_frames.py)
        camera = None
        if config.clip is not None:
            from viewer.app.relit_frames import RelitFrames
            from viewer.app.timeline import ClipTimeline

            self.timeline = ClipTimeline(self.window.ctx, config.clip, (config.size, config.max_size))
            self.timeline.wake = self.window.wake
            self.relit = RelitFrames(self.window.ctx, self.timeline)
            self.relit.wake = self.window.wake
            camera = self.timeline.frames.background_camera(self.timeline.frames.shown(0)[1])
        self.session = Session(self.window.ctx, sc, config.lights, config.environment, config.options, look, camera)
        self.plate = None  # the plate the person is put into (viewer/app/plate_view.py), or None
        if config.plate is not None:
            from viewer.app.plate_view import PlateView

            self.plate = PlateView(self.window.ctx, *config.plate)
            self.plate.notes = list(config.plate_notes)
        self.moving_person = False  # the person being dragged on the plate
        if self.timeline is not None:
            self.timeline.began(self.session)
        self.drawn = None  # the texture drawn last (what stays while a clip's next frame is drawn)
        self.pace = PreviewPace()  # the drag preview's level, from the dragged frames' times (viewer/app/preview.py)
        self.previewed = False  # a preview frame shows: the next full frame comes coarse first (settle)
        self.session.set_placed(config.rig, record=False)
        self.session.wake = self.window.wake
        self.env_path = config.env_path
        self.n_lights = config.lights_count  # not the count of a light file the window opened with
        self.preset = config.preset
        self.view = ix.ViewState()  # zoom and pan; the rotation and exposure are the session's look
        if self.auto_exposure:
            self.frames.apply_auto_exposure()
        self.dragging = False
        self.drag_applied = (0.0, 0.0)  # drag motion already turned into rotation (pixels)
        self.panning = False
        self.last_motion = 0.0
        self.job: LightJob | None = None
        self.scene_job: SceneJob | None = None
        # the child processes that fit maps and infer photos, started on first use (the fitter's when the
        # file browser opens) and kept (torch loads once)
        self.workers = {"lights": ChildWorker(), "photo": ChildWorker()}
        self.recording = None
        self.message = ""
        self.aiming: int | None = None  # the placed light the next click on the person aims
        self.error = ""
        self.log = FrameLog()  # what the frames took (viewer/app/frame_log.py)
        self.switched = False  # a finished job was applied (a new map's lights, a new person) and is not shown yet
        self.held: HeldLighting | None = None  # what the panel shows meanwhile: the picture's lighting (hold_panel)
        self.switch_message = ""  # said when the switch shows
        self.settling: Engine | None = None  # the preview engine whose full-quality frame shows while the sharp one is drawn
        self.settled_key = b""  # the session's state (Session.state_key) that frame shows
        self.frame_start = time.perf_counter()
        self.expose_pending = False  # auto exposure to set from the next complete frame (exposed_again)
        self.panel = PanelState()
        self.captures: list[str] = []
        self.saves: list = []  # SaveJob: frames saved with S whose files are being written
        self.videos: list[str] = []
        self.state_file = StateFile(config.state_file) if config.state_file is not None else None
        self.thumbnail = MapThumbnail(self.window.ctx)
        self.shown = self._showing()  # the map the picture on screen was made under: what the panel shows
        start = (Path(config.plate[0].source).parent if config.plate is not None and config.plate[0].source  # near the plates
                 else config.env_path.parent if config.env_path else Path.cwd())
        self.browser = FileBrowser(start, OPENS)
        self.actions = Actions(self)
        self.recorder = Recorder(self)  # frames saved with S and recordings
        self.jobs = JobPolling(self)
        self.controls = Controls(self)

    def hold_panel(self):
        """Before a job's result changes the session: the panel keeps showing the lighting the picture
        on screen was made under (its controls disabled) until the new frame shows (else the
        longitude and the lights' list would change half a second before the picture)."""
        if self.held is None:
            s = self.session
            self.held = HeldLighting(s.look, s.sigma.copy(), s.rotated_lights(), s.ground_shown)

    def show_switched(self):
        """The frame that shows what a job loaded: the panel shows it too, with its message."""
        self.shown = self._showing()
        self.held = None
        if self.switch_message:
            self.message, self.switch_message = self.switch_message, ""
            print(self.message, flush=True)

    def _showing(self) -> tuple:
        """(map path, its pixels, the map's lights) of the state now: the panel draws the map's name,
        thumbnail and light dots from the picture's, so they change the frame the picture does."""
        return self.env_path, self.session.environment, self.session.lights

    # ------------------------------------------------------------------ geometry
    def image_area(self) -> tuple[float, float, float, float]:
        w, h = self.window.size
        return 0.0, 0.0, float(max(w - panel_width(w), 1)), float(max(h, 1))

    def image_rect(self, shown: Engine | None = None) -> tuple[float, float, float, float]:
        """Where the image is drawn: the current person's frame, or ``shown``'s (the engine whose
        picture is drawn: the person before, while a new one comes in, keeps its own shape)."""
        _, _, aw, ah = self.image_area()
        if self.plate is not None:
            size = self.plate.size
        else:
            size = (shown.scene if shown is not None else self.session.scene).output_size  # a preview's: the same shape
        return ix.image_rect(size, (aw, ah), self.view.zoom, self.view.pan)

    @property
    def replaying(self) -> bool:
        """Whether the recording, not the user, sets the lighting now: a turn, a clip's frames, or a
        captured interaction being rendered."""
        rec = self.recording
        return isinstance(rec, (TurntableRecording, ClipRecording)) or (isinstance(rec, InteractionRecording) and not rec.capturing)

    def picture(self, eng) -> np.ndarray:
        """(H, W, 3) uint8: the frame ``eng`` shows, as recorded (a clip's frame without the person: the background
        alone; on a plate, the person in it at the window's copy's size)."""
        if self.plate is not None:
            return self.plate.picture(eng, (self.session.state_key(), eng.refined_current),
                                      person=self.timeline is None or self.timeline.has_person)
        return self.timeline.picture(eng) if self.timeline is not None else eng.output.read_display()

    def picture_hdr(self, eng) -> np.ndarray:
        """(H, W, 3) float32: :meth:`picture`'s linear HDR, as saved with S."""
        return self.timeline.picture_hdr(eng) if self.timeline is not None else eng.output.read_output_hdr()[..., :3]

    def _write_state(self, force: bool = False):
        if self.state_file is not None:
            self.state_file.write(self, force)

    def _fit_panel(self):
        """A window taller than the panel's content where the screen has room: nothing is cut off
        and no scrolling is needed at first (a smaller screen keeps the panel's scroll bar)."""
        w, h = self.window.size
        need = int(np.ceil(self.panel.height))
        screen = self.window.screen_height()
        if need > h and screen is not None:
            self.window.resize(w, min(need, max(screen - 40, h)))

    def run(self) -> int:
        from viewer.app.panel import draw_panel, draw_progress

        w = self.window
        previous = signal.signal(signal.SIGTERM, lambda *_: w.close()) if os.name == "posix" else None
        kind = ""
        try:
            while not w.should_close:
                # a slider let go: the loop runs on until its full-quality frame replaces the preview; a
                # "warm" frame: on until the drag preview's engines are ready (a step a frame, not one per
                # IDLE_WAIT); a new map or person: on until its frame, drawn over budgeted frames, shows
                busy = (self.dragging or self.panning or self.recording is not None or self.settling is not None
                        or self.switched or kind in ("warm", "prepare") or time.perf_counter() - self.panel.adjusted < 2 * STILL_SECONDS)
                waiting = self.job is not None or self.scene_job is not None or self.session.refining
                timeout = None if busy else (JOB_WAIT if waiting else IDLE_WAIT)
                due = self.timeline.seconds_to_next() if self.timeline is not None else None
                if timeout is not None and due is not None:  # a clip playing: until its next frame is due (or read: wake)
                    timeout = min(timeout, max(due, 0.002))
                w.wait(timeout)
                start = self.frame_start = time.perf_counter()
                w.begin_frame()
                self.controls.handle()
                for path in w.take_dropped():
                    self.actions.open_file(Path(path))
                self.jobs.saves_written()
                self.jobs.poll()
                self.clip.advance()
                self.session.poll_refinement()
                eng, kind = self.frames.next_frame()
                if kind == "idle" and self.clip.prepare_relit():
                    kind = "prepare"  # (the loop goes on at once while there is more)
                if self.plate is not None and self.timeline is not None and eng is self.session.outgoing:
                    self.drawn = self.plate.texture  # a clip's next person still being drawn: what was drawn stays
                elif self.plate is not None:  # the person in the plate, composited again when either changed
                    self.drawn = self.plate.frame_texture(eng, (self.session.state_key(), eng.refined_current),
                                                           settled=not self.moving_person,
                                                           person=self.timeline is None or self.timeline.has_person)
                    if self.timeline is not None:
                        self.timeline.drew(self.timeline.current[0])
                else:
                    self.drawn = self.clip.texture(eng)
                w.draw_image(self.drawn, self.image_rect(eng), self.image_area())
                # the panel after the picture is drawn: what it says (a clip's frame, the lighting held while a new
                # one comes in) is of that picture; what its widgets change (engines made again, a plate removed)
                # is drawn from the next frame, never a texture it released in this one
                draw_panel(self)
                draw_progress(self)
                if self.log.count == 0:
                    self._fit_panel()
                w.end_frame()
                ms = self.log.record(start, kind)
                if kind == "drag":
                    self.pace.record(ms)
                self._write_state()
        finally:
            try:
                if self.recording is not None:
                    self.recorder.finish_recording(stopped=True)
                self._write_state(force=True)
            finally:
                for job in self.saves:
                    job.stop()  # a saved frame's files are written whole before the window ends
                for job in (self.job, self.scene_job):
                    if job is not None:
                        job.stop()  # a fit or an inference ends at once (its child is killed)
                for worker in self.workers.values():
                    worker.close()
                if self.timeline is not None:
                    self.timeline.release()
                    self.relit.release()
                self.session.release()
                if self.plate is not None:
                    self.plate.release()
                self.thumbnail.release()
                w.release()
            if previous is not None:
                signal.signal(signal.SIGTERM, previous)
        return 0


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
