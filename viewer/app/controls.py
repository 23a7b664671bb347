"""The window's mouse and keys, read once a frame from imgui: a drag turns the lighting (on a plate, a
drag on the person moves them and the wheel on them scales them), the right
button pans, the wheel changes the exposure (with Ctrl: zooms), a click aims a placed light, and
the keys of the viewer's table (viewer/app/layout.py) save, record, compare and undo; for a clip,
space plays and pauses and the arrows step a frame."""

from __future__ import annotations

import time
from dataclasses import replace

from viewer.app import interaction as ix


class Controls:
    def __init__(self, app):
        self.app = app

    def _on_plate(self, x: float, y: float) -> tuple[float, float]:
        """The image-area point (x, y) as fractions of the plate shown."""
        rx, ry, w, h = self.app.image_rect()
        return (x - rx) / max(w, 1.0), (y - ry) / max(h, 1.0)

    def _dragged(self) -> tuple[float, float]:
        """The left button's motion (window pixels) since the last call of this drag: from imgui's own press
        position, so nothing is lost between the press and the first frame that sees it, nor before the release."""
        from imgui_bundle import imgui

        if not (imgui.is_mouse_down(0) or imgui.is_mouse_released(0)):
            return 0.0, 0.0
        total = imgui.get_mouse_drag_delta(0, 0.0)
        dx, dy = total.x - self.app.drag_applied[0], total.y - self.app.drag_applied[1]
        self.app.drag_applied = (total.x, total.y)
        return dx, dy

    def handle(self):
        from imgui_bundle import imgui

        io = imgui.get_io()
        mx, my = io.mouse_pos.x, io.mouse_pos.y
        ax, ay, aw, ah = self.app.image_area()
        over_image = ax <= mx < ax + aw and ay <= my < ay + ah and not io.want_capture_mouse
        recording_turn = self.app.replaying  # the lighting is the recording's, not the mouse's
        now = time.perf_counter()
        plate = self.app.plate
        if self.app.aiming is not None and imgui.is_mouse_clicked(0) and over_image:
            self.app.actions.aim_at(mx - ax, my - ay)
        elif (imgui.is_mouse_clicked(0) and over_image and plate is not None and plate.holds(*self._on_plate(mx - ax, my - ay))
              and not recording_turn):  # (a recording's frames keep the person where they stood)
            self.app.moving_person = True  # the person dragged on the plate: their feet follow the mouse
            self.app.drag_applied = (0.0, 0.0)
        elif imgui.is_mouse_clicked(0) and over_image and not recording_turn:
            self.app.dragging = True
            self.app.drag_applied = (0.0, 0.0)
            self.app.pace.start_drag()
        if self.app.dragging:
            dx, dy = self._dragged()
            if dx or dy:
                self.app.session.look = ix.dragged(self.app.session.look, dx, dy)
                self.app.last_motion = now
            if not imgui.is_mouse_down(0):
                self.app.dragging = False
        if self.app.moving_person:
            dx, dy = self._dragged()
            if dx or dy:
                _, _, w, h = self.app.image_rect()
                plate.moved(dx / max(w, 1.0), dy / max(h, 1.0))
            if not imgui.is_mouse_down(0):
                self.app.moving_person = False
                self.app.actions.placed_on_plate()
        if imgui.is_mouse_clicked(1) and over_image:
            self.app.panning = True
        elif self.app.panning:
            if imgui.is_mouse_down(1):
                self.app.view = ix.panned(self.app.view, io.mouse_delta.x, io.mouse_delta.y)
            else:
                self.app.panning = False
        if over_image and io.mouse_wheel:
            if io.key_ctrl:
                self.app.view = ix.zoomed(self.app.view, io.mouse_wheel, cursor=(mx - ax, my - ay), area=(aw, ah))
            elif plate is not None and plate.holds(*self._on_plate(mx - ax, my - ay)):  # on the person: scaled about their feet
                if not recording_turn:
                    plate.scaled(io.mouse_wheel)
                    self.app.actions.placed_on_plate()
            else:
                self.app.session.look = ix.wheeled(self.app.session.look, io.mouse_wheel)
        shortcuts = self.app.window.take_shortcuts()
        if io.want_capture_keyboard:
            return
        if imgui.is_key_pressed(imgui.Key.s, False):
            self.app.recorder.save_frame()
        if imgui.is_key_pressed(imgui.Key.r, False):
            self.app.recorder.toggle_recording("live")
        if imgui.is_key_pressed(imgui.Key.t, False):
            self.app.recorder.toggle_recording("turntable")
        t = self.app.timeline
        if t is not None and self.app.recording is None:
            if imgui.is_key_pressed(imgui.Key.space, False):
                t.play()
            # the arrows repeat when held (frame after frame); Home and End do not
            for key, repeat, frame in ((imgui.Key.left_arrow, True, t.index - 1), (imgui.Key.right_arrow, True, t.index + 1),
                                       (imgui.Key.home, False, 0), (imgui.Key.end, False, t.count - 1)):
                if imgui.is_key_pressed(key, repeat):
                    t.play(False)
                    t.seek(frame)
        if imgui.is_key_pressed(imgui.Key.f, False):
            self.app.view = replace(self.app.view, zoom=1.0, pan=(0.0, 0.0))
        if imgui.is_key_pressed(imgui.Key._0, False):
            self.app.session.update(yaw=0.0, tilt=0.0)
        if imgui.is_key_pressed(imgui.Key.b, False):
            self.app.actions.toggle_compare()
        if imgui.is_key_pressed(imgui.Key.g, False):
            self.app.session.update(ground=not self.app.session.ground_shown)
        for key in shortcuts:
            if key == "undo":
                self.app.message = "undone" if self.app.session.undo() else "nothing to undo"
            else:
                self.app.message = "redone" if self.app.session.redo() else "nothing to redo"
        if imgui.is_key_pressed(imgui.Key.q, False) or imgui.is_key_pressed(imgui.Key.escape, False):
            self.app.window.close()
