"""The desktop window: GLFW, an OpenGL 4.1 core context wrapped by moderngl, imgui-bundle's GLFW
backend (with implot), and drawing the engine's display image into the image area.

Import order matters: importing ``imgui_bundle`` first points pyGLFW at imgui-bundle's own GLFW
library (../shared/docs/STACK.md).
"""

from __future__ import annotations

import os

import glfw
import moderngl
from imgui_bundle import imgui, implot  # noqa: I001  (before glfw, see above)

from viewer.errors import InputError
from viewer.gl.programs import shared_programs

SHORTCUTS = {glfw.KEY_Z: "undo", glfw.KEY_Y: "redo"}  # with Ctrl


class Window:
    def __init__(self, width: int, height: int, title: str = "relight"):
        if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            raise InputError(None, "cannot open a window: no display (set DISPLAY, or run under xvfb-run; "
                             "`relight render` works without one)")
        if not glfw.init():
            raise InputError(None, f"cannot open a window: GLFW failed to start on display {os.environ.get('DISPLAY')!r}")
        glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 4)
        glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 1)
        glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
        glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
        self.handle = glfw.create_window(width, height, title, None, None)
        if not self.handle:
            glfw.terminate()
            raise InputError(None, "cannot open a window with an OpenGL 4.1 core context on this display")
        glfw.make_context_current(self.handle)
        glfw.swap_interval(0)  # no vsync wait: frame times are the work's (llvmpipe has no vsync anyway)
        self.ctx = moderngl.create_context(require=410)
        imgui.create_context()
        implot.create_context()
        imgui.get_io().set_ini_filename("")  # no imgui.ini written into the user's folder
        from imgui_bundle.python_backends.glfw_backend import GlfwRenderer

        self.imgui = GlfwRenderer(self.handle)
        # The backend drops cursor positions while the window lacks keyboard focus (which, without
        # a window manager, it may never get); hovering and dragging should not depend on focus.
        io = imgui.get_io()
        glfw.set_cursor_pos_callback(self.handle, lambda _w, x, y: io.add_mouse_pos_event(float(x), float(y)))
        self.dropped: list[str] = []  # files dropped on the window, taken by the app's next frame
        glfw.set_drop_callback(self.handle, self.on_drop)
        # Ctrl+Z / Ctrl+Y read from each key event's own modifiers: imgui's Ctrl state is the frame's,
        # and a Ctrl let go before the Z (xdotool does so, as do quick hands) arrives in the same
        # frame as the Z, which then read as a bare Z and the undo was lost
        self.shortcuts: list[str] = []
        backend_keys = self.imgui.keyboard_callback

        def on_key(handle, key, scancode, action, mods):
            backend_keys(handle, key, scancode, action, mods)
            if action == glfw.PRESS and mods & glfw.MOD_CONTROL and key in SHORTCUTS:
                self.shortcuts.append(SHORTCUTS[key])

        glfw.set_key_callback(self.handle, on_key)
        glfw.focus_window(self.handle)
        self._programs = shared_programs(self.ctx)  # the engines drawing into this window use the same
        self._sampler = self.ctx.sampler(filter=(moderngl.LINEAR, moderngl.LINEAR), repeat_x=False, repeat_y=False)
        self._vao = None

    # ------------------------------------------------------------------ loop
    def on_drop(self, _handle, paths):
        """GLFW's drop callback: the paths of the files dropped on the window."""
        self.dropped.extend(str(p) for p in paths)
        self.wake()

    def take_dropped(self) -> list[str]:
        paths, self.dropped = self.dropped, []
        return paths

    def take_shortcuts(self) -> list[str]:
        """The Ctrl shortcuts pressed since the last call ("undo", "redo"), in order."""
        keys, self.shortcuts = self.shortcuts, []
        return keys

    @property
    def should_close(self) -> bool:
        return bool(glfw.window_should_close(self.handle))

    def close(self):
        glfw.set_window_should_close(self.handle, True)

    def wait(self, timeout: float | None):
        """Process events; wait up to ``timeout`` seconds for one (None: do not wait)."""
        if timeout:
            glfw.wait_events_timeout(timeout)
        else:
            glfw.poll_events()

    @staticmethod
    def wake():
        """Wake :meth:`wait` from another thread."""
        glfw.post_empty_event()

    def begin_frame(self):
        self.imgui.process_inputs()
        imgui.new_frame()

    @property
    def framebuffer_size(self) -> tuple[int, int]:
        return tuple(glfw.get_framebuffer_size(self.handle))

    @property
    def size(self) -> tuple[int, int]:
        return tuple(glfw.get_window_size(self.handle))

    def draw_image(self, texture: moderngl.Texture, rect, area):
        """Clear, then draw ``texture`` into ``rect`` = (x, y, w, h) window pixels from the top left,
        clipped to ``area`` = (x, y, w, h)."""
        fw, fh = self.framebuffer_size
        ww, wh = self.size
        sx, sy = fw / max(ww, 1), fh / max(wh, 1)
        screen = self.ctx.screen
        screen.use()
        self.ctx.scissor = None
        self.ctx.viewport = (0, 0, fw, fh)
        self.ctx.clear(0.08, 0.08, 0.09)
        x, y, w, h = rect
        ax, ay, aw, ah = area
        self.ctx.scissor = (int(ax * sx), int(fh - (ay + ah) * sy), int(aw * sx), int(ah * sy))
        self.ctx.viewport = (int(round(x * sx)), int(round(fh - (y + h) * sy)), max(int(round(w * sx)), 1), max(int(round(h * sy)), 1))
        prog = self._programs.get("fullscreen.vert.glsl", "window_image.frag.glsl")
        if self._vao is None:
            self._vao = self.ctx.vertex_array(prog, [])
        texture.use(0)
        self._sampler.use(0)
        prog["image"] = 0
        self._vao.render(moderngl.TRIANGLES, vertices=3)
        self._sampler.clear(0)
        self.ctx.scissor = None
        self.ctx.viewport = (0, 0, fw, fh)

    def screen_height(self) -> int | None:
        """The height of the primary monitor's work area (without panels and docks), or None."""
        monitor = glfw.get_primary_monitor()
        if not monitor:
            return None
        try:
            return int(glfw.get_monitor_workarea(monitor)[3])
        except (AttributeError, glfw.GLFWError):
            return None

    def set_title(self, title: str):
        glfw.set_window_title(self.handle, title)

    def resize(self, width: int, height: int):
        glfw.set_window_size(self.handle, int(width), int(height))

    def show_message(self, text: str, fraction: float | None = None, bar: str = ""):
        """Draw one frame holding only ``text`` (progress while the window waits on work that
        blocks its thread, such as a photo's inference), with a bar of ``fraction`` done labelled
        ``bar`` (the stage and the time left) when given. Q, Esc or the window closed stop the work
        (KeyboardInterrupt, as Ctrl-C does: what is done is kept)."""
        self.wait(None)
        self.begin_frame()
        if self.should_close or imgui.is_key_pressed(imgui.Key.q, False) or imgui.is_key_pressed(imgui.Key.escape, False):
            imgui.end_frame()
            raise KeyboardInterrupt("stopped in the window")
        w, h = self.size
        imgui.set_next_window_pos(imgui.ImVec2(0, 0))
        imgui.set_next_window_size(imgui.ImVec2(float(w), float(h)))
        flags = imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_saved_settings
        imgui.begin("message", None, flags)
        size = imgui.calc_text_size(text)
        imgui.set_cursor_pos(imgui.ImVec2(max((w - size.x) / 2, 8.0), max((h - size.y) / 2, 8.0)))
        imgui.text(text)
        if fraction is not None:
            width = min(w - 16.0, 480.0)
            imgui.set_cursor_pos(imgui.ImVec2(max((w - width) / 2, 8.0), max((h - size.y) / 2, 8.0) + 2 * size.y))
            imgui.progress_bar(float(fraction), imgui.ImVec2(width, 0), bar)
            imgui.set_cursor_pos_x(max((w - width) / 2, 8.0))
            imgui.text_disabled("Q or Esc stops (what is done is kept)")
        imgui.end()
        fw, fh = self.framebuffer_size
        self.ctx.screen.use()
        self.ctx.scissor = None
        self.ctx.viewport = (0, 0, fw, fh)
        self.ctx.clear(0.08, 0.08, 0.09)
        from OpenGL import GL

        for _ in range(16):  # engine work (texture reads) can leave errors the backend would raise
            if self.ctx.error == "GL_NO_ERROR":
                break
        GL.glUseProgram(0)  # the backend restores the bound program: never one an engine has since released
        self.end_frame()

    def end_frame(self):
        self.ctx.screen.use()  # the panel's widgets may have rendered since the picture was drawn (an engine's framebuffer bound)
        imgui.render()
        self.imgui.render(imgui.get_draw_data())
        glfw.swap_buffers(self.handle)

    def release(self):
        if self._vao is not None:
            self._vao.release()
        self._sampler.release()
        self._programs.release()
        self.imgui.shutdown()
        implot.destroy_context()
        imgui.destroy_context()
        glfw.destroy_window(self.handle)
        glfw.terminate()
