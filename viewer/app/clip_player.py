"""A clip in the window: its frame due brought to the session, the picture drawn for it (a relit frame
prepared ahead while the window is idle, or what stays on screen until the session's frame is whole),
a recording's frames read whole, and the clip's timeline ended when another person opens."""

from __future__ import annotations

import time

from viewer.app.preview import STILL_SECONDS, SWAP_BUDGET
from viewer.app.recording import ClipRecording


class ClipPlayer:
    """A clip in the window (the app's ``timeline`` and ``relit`` frames): the frame shown, drawn and
    prepared ahead (module docstring)."""

    def __init__(self, app):
        self.app = app

    def advance(self):
        """A clip's frame due (playing) or asked for (the slider) brought to the session; a new person's
        frame is drawn over budgeted frames as a new photo is, the frame before staying meanwhile."""
        t = self.app.timeline
        if t is None or self.app.recording is not None or self.app.switched or self.app.scene_job is not None:
            return
        t.tick()
        if t.playing and self._from_relit():
            return  # its picture is drawn (_texture): the session is brought to the frame where playing stops
        try:
            change = t.advance(self.app.session)
        except Exception as exc:  # a frame's maps unreadable (the bundle changed on disk): said, the clip pauses
            self.app.actions.report(f"frame {t.index + 1} of the clip", exc)
            t.forget(t.index)
            t.play(False)
            t.seek(t.current[0] if t.current is not None else 0)
            return
        if change == "person":
            self.app.switched = True

    def record_frame(self, rec: ClipRecording) -> bool:
        """The recording's next frame brought to the session, whole (its scene read now); False when
        it could not be read (said; the recording ends there, its file removed)."""
        self.app.timeline.seek(rec.done)
        try:
            self.app.timeline.advance(self.app.session, wait=True)
        except Exception as exc:  # a frame's maps unreadable (the bundle changed on disk)
            self.app.timeline.forget(rec.done)
            self.app.recorder.recording_failed(rec, exc)
            return False
        return True

    def end(self):
        """Another person opened: the clip's timeline goes (its frames no longer shown; a recording of
        it ends with the frames recorded)."""
        if isinstance(self.app.recording, ClipRecording):
            self.app.recorder.finish_recording(stopped=True)
        if self.app.timeline is not None:
            self.app.timeline.release()
            self.app.relit.release()
            self.app.timeline = self.app.relit = None
        if self.app.plate is not None:  # the new person is placed by their own frame, not the clip's first one
            self.app.plate.unanchor()
        self.app.session.camera_turn, self.app.session.camera_height = (0.0, 0.0), 0.0

    def _from_relit(self) -> bool:
        """Whether the clip's frame asked for has its relit picture ready under the lighting now (on a plate
        none is: the person is composited into it live)."""
        if self.app.relit is None or self.app.plate is not None:
            return False
        self.app.relit.follow(self.app.session)
        return self.app.relit.ready(self.app.timeline.index)

    def texture(self, eng):
        """What the window draws for ``eng``'s frame: its display, or a clip's frame (the timeline tells
        which frame is on screen, :meth:`ClipTimeline.drew`). A clip's frame asked for and not in the
        session yet (being read or drawn) shows its relit picture when ready; else what is on screen
        stays (a relit picture, the timeline's picture of a frame with no one in it, the person before's
        display) until the session's frame is drawn whole."""
        t = self.app.timeline
        if t is None:
            return eng.display
        outgoing = eng is self.app.session.outgoing
        if outgoing or not t.in_session:
            if self._from_relit():
                t.drew(t.frames.shown(t.index)[0])
                return self.app.relit.texture(t.index)
            drawn = self.app.drawn
            kept = drawn is not None and (drawn is self.app.relit.own_texture or outgoing and drawn is t.own_texture)
            if kept or outgoing:
                return self.app.drawn if kept else eng.display
        t.drew(t.current[0])
        return t.texture(eng, self.app.session.state_key())

    def prepare_relit(self) -> bool:
        """An idle frame (nothing to draw, no one dragging, paused) relights a slice of the clip's next
        frame not ready (:meth:`RelitFrames.prepare`); False when there was none to do."""
        if (self.app.relit is None or self.app.plate is not None or self.app.timeline.playing or self.app.recording is not None
                or self.app.dragging or time.perf_counter() - self.app.panel.adjusted < STILL_SECONDS):
            return False
        self.app.relit.follow(self.app.session)
        return self.app.relit.prepare(self.app.session, max(SWAP_BUDGET - (time.perf_counter() - self.app.frame_start), 0.005))
