"""What the window draws next and how: a cheap preview while the lighting is dragged, the full-quality
frame coarse first then sharpened over budgeted frames when it stops, a new map or person brought in
over budgeted frames, a recording's frames whole; and the automatic exposure set from a new state's
first complete frame."""

from __future__ import annotations

import time

from viewer.app.preview import STILL_SECONDS, SWAP_BUDGET
from viewer.app.recording import ClipRecording, InteractionRecording, TurntableRecording
from viewer.output.render import photo_exposure


class FramePlan:
    """The window's next frame (:meth:`next_frame`) and its automatic exposure, from the app's state (its
    session, recording, drag and the settling frame kept on it; module docstring)."""

    def __init__(self, app):
        self.app = app

    def apply_auto_exposure(self):
        """Exposure from the photo's own brightness under the current lights (a no-op, 0 stops,
        for a scene without a photo)."""
        s = self.app.session
        eng = s.render(preview=False)
        e = self.app.auto_value = photo_exposure(eng, s.scene, s.look.tonemap)
        s.update(exposure=e)

    def exposed_again(self):
        """After new lights or a new person: auto exposure, unless the user has set one since, set
        from the new state's first complete frame (:meth:`_render`), before it is shown."""
        self.app.expose_pending = self.app.auto_exposure and self.app.session.look.exposure == self.app.auto_value

    # ------------------------------------------------------------------ frame
    def next_frame(self) -> tuple[object, str]:
        """Render the current state; returns the engine to show and what kind of frame it was."""
        s = self.app.session
        rec = self.app.recording
        if isinstance(rec, TurntableRecording):
            s.update(yaw=rec.next_yaw())
        if isinstance(rec, ClipRecording) and not self.app.clip.record_frame(rec):
            return s.final, "record"
        if isinstance(rec, InteractionRecording):
            if rec.capturing:
                rec.capture(s.look, s.placed, s.sigma)
            else:
                self.app.recorder.apply_moment(rec.moment(rec.done))
        capturing = isinstance(rec, InteractionRecording) and rec.capturing
        now = time.perf_counter()
        moving = self.app.dragging and now - self.app.last_motion < STILL_SECONDS
        adjusting = not moving and now - self.app.panel.adjusted < STILL_SECONDS  # a panel slider held: soft shadows kept
        switching = self.app.switched and rec is None  # a new map or person: brought in over frames of SWAP_BUDGET
        preview = (moving or adjusting) and (rec is None or capturing) and not switching
        s.preview_level = self.app.pace.level
        if self.app.settling is not None and self.app.settling not in s.previews.engines.values():
            self.app.settling = None  # its engines were made again (a quality preset): the final frame comes whole
        if preview or switching or rec is not None:
            self.app.settling = None
            self.app.previewed = self.app.previewed and preview  # a new map or person, or a recording, comes whole
        elif self.app.previewed or (self.app.settling is not None and self.app.settled_key != s.state_key()):
            # the lighting stopped (or changed again while the sharp frame was drawn: a key, the wheel):
            # its full-quality frame at the preview's level first (the look's soft shadows and skin),
            # then the final engine's over budgeted frames behind it ("sharpen")
            self.app.previewed = False
            self.app.settling = s.render_coarse()
            self.app.settled_key = s.state_key()
            return self.app.settling, "settle"
        rendered = s.preview if preview else s.final
        before = sum(rendered.kit.counters.values())
        left = max(SWAP_BUDGET - (now - self.app.frame_start), 0.0)  # of the frame's budget for budgeted work
        # a new map or person, or the sharp frame behind a coarse one, is drawn over budgeted frames
        budget = left if switching or self.app.settling is not None else None
        expose = switching and self.app.expose_pending  # auto exposure from the new HDR, before its frame is drawn
        eng = s.render(preview=preview, hard=moving, budget=budget, display=not expose)
        worked = sum(rendered.kit.counters.values()) != before
        if expose and rendered.composited:
            self.app.expose_pending = False
            e = self.app.auto_value = photo_exposure(rendered, s.scene, s.look.tonemap)
            s.update(exposure=e)
            return eng, "load"  # the next pass draws the frame at that exposure
        if switching and not rendered.complete:
            return eng, "load"  # the last complete frame stays on screen while the rest is done
        if self.app.settling is not None:
            if not rendered.complete:
                return self.app.settling, "sharpen"  # the coarse full-quality frame stays while the sharp one is drawn
            self.app.settling = None
            return eng, "update"
        if rec is not None and not capturing:
            if self.app.switched:  # a recording's frames are whole: what a job loaded shows in this one
                self.app.show_switched()
            try:
                rec.add(self.app.picture(eng))
            except Exception as exc:
                self.app.recorder.recording_failed(rec, exc)
                return eng, "record"
            if rec.finished:
                self.app.recorder.finish_recording()
            return eng, "record"
        if self.app.switched:  # "switch": the frame that shows what a job loaded (its work may be done before _render)
            self.app.switched = False
            self.app.show_switched()
            if self.app.expose_pending:  # switched while recording, at full quality: exposed from the next frame on
                self.app.expose_pending = False
                self.apply_auto_exposure()
            return eng, "switch"
        if not worked:  # "load": nothing to redraw while lights are fitted or a scene opened off this thread
            if self.app.job is not None or self.app.scene_job is not None:
                return eng, "load"
            if preview:
                return eng, "idle"  # a dragged frame with no motion: no preview engine is made mid-drag
            # "warm": an idle frame makes the drag preview's engine, so the first dragged frame is a preview's
            playing = self.app.timeline is not None and self.app.timeline.playing  # the next frame's scene soon replaces these
            return eng, "warm" if not playing and s.warm_preview(left) else "idle"
        self.app.previewed = preview
        return eng, ("drag" if moving else "adjust") if preview else "update"
