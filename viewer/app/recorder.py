"""The window's captures: a frame saved with S (its files written on a thread), recordings of a turn,
of the user's interaction (captured, then replayed at full quality) and of a clip, each started,
stopped, finished or failed with what the user had kept."""

from __future__ import annotations

import json
import sys
import time
from dataclasses import asdict
from pathlib import Path

from viewer.app.jobs import PlateSaveJob, SaveJob
from viewer.app.recording import ClipRecording, InteractionRecording, TurntableRecording
from viewer.app.state_file import look_json
from viewer.files.imageio import MARK


class Recorder:
    """The window's captures and recordings (module docstring); its state: the turn's frames, the captures' count."""

    def __init__(self, app):
        self.app = app
        self._capture_index = 0
        self.turn_frames = app.config.record_frames  # a 360 turn's frames (relight view --record-frames; the panel's slider)

    def set_turn_frames(self, frames: int):
        self.turn_frames = int(frames)

    def capture_stem(self) -> Path:
        """A name no file has yet (another window saving in the same second, a user's file): a capture
        never replaces anything (nor do the files beside it: a clip's frames before its audio joins them,
        its audio's sidecar)."""
        stamp = time.strftime("%Y%m%d-%H%M%S")
        folder = self.app.config.out_dir
        while True:
            self._capture_index += 1
            stem = folder / f"relight-{stamp}-{self._capture_index:03d}"
            if not folder.is_dir() or not any(folder.glob(f"{stem.name}.*")):
                return stem

    def save_frame(self):
        try:
            self._save_frame()
        except Exception as exc:  # an unwritable folder, a full disk: reported, the viewer goes on
            self.app.actions.report("saving the frame failed", exc)

    def _save_frame(self):
        """The current state at full quality: display PNG, HDR EXR and a JSON of lights and look, read
        here (GL) and written on a thread (:class:`viewer.app.jobs.SaveJob`: encoding them was ~0.5 s of
        the window's frame at 2048 pixels); :meth:`saved` says when they are there."""
        t = self.app.timeline
        if t is not None and not t.in_session:  # the frame asked for (on screen from its relit picture, or coming)
            t.advance(self.app.session, wait=True)
        eng = self.app.session.render(preview=False)
        stem = self.capture_stem()
        state = {"look": look_json(self.app), "map": str(self.app.env_path) if self.app.env_path else None, "preset": self.app.preset}
        state["lights"] = self.app.session.rendered_lights().to_json()  # what was rendered: the map's and the placed
        state["rig"] = [asdict(p) for p in self.app.session.placed]
        if t is not None:  # which frame of which clip (as relight render's frames count them, from 0): the one saved
            state["clip"] = {"bundle": str(t.bundle.path), "frame": t.current[0], "seconds": round(t.times[t.current[0]], 6)}
        plate = self.app.plate
        if plate is not None and t is not None and not t.has_person:  # a clip's frame with no one in it: the plate alone
            state["plate"] = plate.to_json()
            self.app.saves.append(SaveJob(stem, plate.plate.srgb, plate.plate.linear, json.dumps({**state, MARK[0]: MARK[1]}, indent=2)
                                          + "\n", wake=self.app.window.wake))
            self.app.message = f"saving {stem.name}.png (+ .exr, .json): the plate, no one in this frame, in {stem.parent.resolve()}"
            return
        if plate is not None:  # the person into the whole plate, on the save's thread
            from viewer.output.plate_render import read_person

            state["plate"] = plate.to_json()
            self.app.saves.append(PlateSaveJob(stem, read_person(eng), plate.plate, plate.place, plate.horizon,
                                               json.dumps({**state, MARK[0]: MARK[1]}, indent=2) + "\n", wake=self.app.window.wake,
                                               anchor=plate.anchor))
            self.app.message = f"saving {stem.name}.png (+ .exr with the layers, .json) on the plate in {stem.parent.resolve()}"
            return
        self.app.saves.append(SaveJob(stem, self.app.picture(eng), self.app.picture_hdr(eng),
                                      json.dumps({**state, MARK[0]: MARK[1]}, indent=2) + "\n", wake=self.app.window.wake))
        self.app.message = f"saving {stem.name}.png (+ .exr, .json) in {stem.parent.resolve()}"

    def saved(self, job: SaveJob):
        """A save's files are written (or it failed: said in one line)."""
        if job.error:
            self.app.error = job.error
            print(f"relight: error: {job.error}", file=sys.stderr, flush=True)
            return
        png = job.result
        self.app.captures.append(str(png))
        self.app.message = f"saved {png.name} (+ .exr, .json) in {png.parent.resolve()}"
        print(f"saved {png.resolve()} {png.with_suffix('.exr').resolve()} {png.with_suffix('.json').resolve()}", flush=True)

    def toggle_recording(self, kind: str):
        rec = self.app.recording
        if isinstance(rec, InteractionRecording) and rec.capturing:
            rec.stop(self.app.session.look, self.app.session.placed,
                     self.app.session.sigma)  # the capture ends: its frames are rendered from the next pass on
            self.app.message = f"rendering {rec.total} frames of {rec.path.name}"
            return
        if rec is not None:
            self.finish_recording(stopped=True)
            return
        if self.app.timeline is not None:
            self.app.timeline.play(False)  # a recording sets the lighting or the frames: the clip's clock stops
        size = self.app.plate.size if self.app.plate is not None else self.app.session.scene.output_size  # on a plate: the plate's copy
        path = self.capture_stem().with_suffix(".mp4")
        try:
            if kind == "turntable":
                self.app.recording = TurntableRecording(path, size, self.app.session.look.yaw, self.turn_frames, self.app.config.fps)
            elif self.app.timeline is not None:  # a clip: R relights its every frame
                self.app.recording = ClipRecording(path, size, self.app.timeline)
            else:
                self.app.recording = InteractionRecording(path, size, self.app.config.fps)
        except Exception as exc:
            self.app.actions.report(f"cannot record to {path}", exc)
            return
        self.app.message = f"recording {path.name}"

    def recording_failed(self, rec, exc: Exception):
        """A recording that could not go on (a frame not written or not read): said, its file left as
        the recording's kind leaves it (:meth:`abort`), and the lighting and the frame back where the user was."""
        self.app.actions.report(f"recording {rec.path} failed", exc)
        self.app.recording = None
        self._restore(rec)
        try:
            rec.abort()
        except Exception:  # the error that matters is the one just reported
            pass

    def _restore(self, rec):
        """After a recording: the lighting (a turn, a replayed interaction) or the clip's frame as the user had them."""
        if isinstance(rec, TurntableRecording):
            self.app.session.update(yaw=rec.start_yaw)
        elif isinstance(rec, ClipRecording):
            if self.app.timeline is not None:
                self.app.timeline.seek(rec.resume)
        elif rec.resume is not None:
            self.apply_moment(rec.resume)

    def apply_moment(self, m):
        s = self.app.session
        s.look = m.look.fitted(len(s.base_lights) + len(m.placed))
        s.set_placed(m.placed, record=False)
        if len(m.sigma) == len(s.sigma):  # the same map's lights (a refit meanwhile keeps the new sigmas)
            s.sigma[:] = m.sigma

    def _render_capture(self, rec: InteractionRecording):
        """A quit during a capture: its frames rendered now (nothing else holds what the user did)."""
        rec.stop(self.app.session.look, self.app.session.placed, self.app.session.sigma)
        print(f"rendering the {rec.total} frames of {rec.path.name} before quitting", flush=True)
        while not rec.finished:
            self.apply_moment(rec.moment(rec.done))
            self.app.session.render()
            rec.add(self.app.picture(self.app.session.final))  # (on a plate: the person in it, the video's size)

    def finish_recording(self, stopped: bool = False):
        rec, self.app.recording = self.app.recording, None
        if isinstance(rec, InteractionRecording):
            try:
                if rec.capturing:
                    self._render_capture(rec)
            finally:
                self._restore(rec)  # back to where the user was
        else:
            self._restore(rec)
        try:
            path = rec.close()
        except Exception as exc:
            self.app.actions.report(f"recording {rec.path} failed", exc)
            return
        how = "stopped after" if stopped and not rec.finished else "recorded"
        self.app.videos.append(str(path))
        note = f" ({rec.note})" if getattr(rec, "note", None) else ""
        self.app.message = f"{how} {rec.done} frames: {path.name} in {Path(path).parent.resolve()}{note}"
        print(f"{how} {rec.done} frames to {Path(path).resolve()}{note}", flush=True)
