"""The viewer's state file (``relight view --state-file``): the look, the lights, the widgets'
places, what is being recorded, fitted or opened, and the frame times, as JSON for scripts, tests
and benchmarks."""

from __future__ import annotations

import json
import time
from dataclasses import asdict, replace
from pathlib import Path

from viewer.files.imageio import write_text


def look_json(app) -> dict:
    """The look shown, with the quality preset it was made at."""
    return replace(app.session.look, preset=app.preset).to_json()


class StateFile:
    """Writes ``path`` atomically, skipping a write that would change nothing but the frame times
    within a second."""

    def __init__(self, path: Path):
        self.path = path
        self._text = ""
        self._time = 0.0

    def write(self, app, force: bool = False):
        """The window's state now (at most once a second when only the frame times changed)."""
        rec = app.recording
        state = {
            "look": look_json(app),
            "sigma": [float(v) for v in app.session.sigma],
            "placed": [asdict(p) for p in app.session.placed],
            "n_lights": len(app.session.sigma),
            "preset": app.preset,
            "map": str(app.env_path) if app.env_path else None,
            "shown_map": str(app.shown[0]) if app.shown[0] else None,  # the picture's (the panel shows it)
            "image_rect": list(app.image_rect()),
            "window_size": list(app.window.size),
            "panel_height": app.panel.height,
            "widgets": app.panel.widgets,
            "panel_right": app.panel.content_right,  # no widget or label past it
            "id_conflicts": app.panel.id_conflicts,
            "recording": None if rec is None else {"kind": rec.kind, "frames": rec.done, "total": rec.total, "path": str(rec.path),
                                                   "capturing": getattr(rec, "capturing", False),
                                                   "seconds": getattr(rec, "seconds", None)},
            "fitting": app.job is not None,
            "opening": None if app.scene_job is None else str(app.scene_job.path),
            "switching": app.switched,  # a job's result applied, its frame not shown yet (the panel held meanwhile)
            "held": app.held is not None,
            "scene_size": list(app.session.scene.output_size),
            "refined": app.session.final.refined_current,
            "refine_error": app.session.refine_error,
            "captures": app.captures,
            "out_dir": str(app.config.out_dir.resolve()),  # where S and R write (--out-dir)
            "videos": app.videos,
            "plate": app.plate.to_json() if app.plate is not None else None,
            # the person's box on the plate (x0, y0, x1, y1), fractions of the plate's width and height
            "plate_box": app.plate.box_fractions() if app.plate is not None else None,
            "plate_notes": app.plate.notes if app.plate is not None else [],
            "message": app.message,
            "error": app.error,
            "gl_threads": app.config.gl_threads,  # llvmpipe's, sized when the window opened (viewer/cli/main.py)
            "preview_level": app.pace.level,  # the drag preview's level (viewer/app/preview.py)
            "switched_at": app.log.switched_at,  # wall clock (time.time) of the frame that last showed a new map or photo
            "longest_frame": app.log.longest,  # (ms, kind) since the start-up's frames
            "settle": app.log.settle,  # after the lighting last stopped: ms to its full-quality frame, and to the sharp one
            "clip": None if app.timeline is None else {
                "index": app.timeline.index, "frames": app.timeline.count, "playing": app.timeline.playing,
                "shown": list(app.timeline.current) if app.timeline.current is not None else None,
                "rate": app.timeline.rate, "played": len(app.timeline.shown_at), "every_frame": app.timeline.every_frame,
                "on_screen": app.timeline.on_screen, "slider_and_words": list(app.panel.clip_shown),
                "relit": app.relit.count if app.relit is not None else 0,
                "camera_turn": list(app.session.camera_turn), "camera_height": app.session.camera_height},  # a clip's timeline
        }
        text = json.dumps(state)
        now = time.monotonic()
        if text == self._text and not force and now - self._time < 1.0:  # frame times: once a second
            return
        self._text, self._time = text, now
        state["frame_count"] = app.log.count
        state["frames"] = [[round(ms, 3), kind] for ms, kind in app.log.frames]
        write_text(self.path, json.dumps(state))
