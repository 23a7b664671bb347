"""What every pass of the engine shares: the GL context, its compiled programs, texture creation,
the full-screen draw, and the pass counters and timings (``Engine.kit``)."""

from __future__ import annotations

import time
from collections import Counter, defaultdict
from contextlib import contextmanager

import moderngl
import numpy as np

from viewer.gl.programs import ProgramCache


class PassKit:
    """The context and its tools, handed to each pass; owns only the full-screen vertex arrays."""

    def __init__(self, ctx: moderngl.Context, programs: ProgramCache, profile: bool = False):
        self.ctx = ctx
        self.programs = programs
        self.counters: Counter = Counter()  # passes run, by name
        self.timings: dict[str, list[float]] = defaultdict(list)  # seconds per pass run (profile only)
        self.profile = profile  # finish GL work around every pass and record its wall time
        self.fullscreen_vaos: dict = {}

    def texture(self, size, components, data=None, dtype="f4", linear=False, repeat=False) -> moderngl.Texture:
        tex = self.ctx.texture(size, components, data=data, dtype=dtype)
        flt = moderngl.LINEAR if linear else moderngl.NEAREST
        tex.filter = (flt, flt)
        tex.repeat_x = repeat
        tex.repeat_y = False
        return tex

    def fullscreen(self, program: moderngl.Program):
        """One full-screen triangle with ``program`` into the bound framebuffer (its viewport and scissor)."""
        vao = self.fullscreen_vaos.get(program.glo)
        if vao is None:
            vao = self.fullscreen_vaos[program.glo] = self.ctx.vertex_array(program, [])
        vao.render(moderngl.TRIANGLES, vertices=3)

    @contextmanager
    def timed(self, name: str, count: bool = True):
        """Count a pass run under ``name`` and, when profiling, time it (GL work finished on both sides)."""
        if count:
            self.counters[name] += 1
        if not self.profile:
            yield
            return
        self.ctx.finish()
        t0 = time.perf_counter()
        yield
        self.ctx.finish()
        self.timings[name].append(time.perf_counter() - t0)

    @contextmanager
    def scratch_target(self, size):
        """A texture and its framebuffer made for one draw and read (RGBA32F of ``size``), released
        after it; the framebuffer bound before is bound again first: moderngl binds its idea of the
        current one again whenever it makes a framebuffer, and a deleted one there is an invalid
        operation that the window's imgui backend then raises, frames later."""
        before = self.ctx.fbo
        tex = self.texture(size, 4)
        fbo = self.ctx.framebuffer(color_attachments=[tex])
        try:
            yield tex, fbo
        finally:
            if before is not None and not isinstance(before.mglo, moderngl.InvalidObject):  # none at first headless;
                before.use()  # a released one (an engine's, headless) stays unbound
            fbo.release()
            tex.release()

    def read(self, tex: moderngl.Texture, components: int, dtype="f4") -> np.ndarray:
        """A texture's pixels as (H, W, components), row 0 at the texture's v = 0."""
        w, h = tex.size
        arr = np.frombuffer(tex.read(), dtype=np.float32 if dtype == "f4" else np.uint8)
        return arr.reshape(h, w, components).copy()

    def release(self):
        for vao in self.fullscreen_vaos.values():
            vao.release()
        self.fullscreen_vaos.clear()


def band_box(size: tuple[int, int], band: int, bands: int) -> tuple[int, int, int, int]:
    """(x, y, width, height): band ``band`` of ``bands`` bands of rows of an image of ``size`` (w, h)."""
    w, h = size
    y0, y1 = band * h // bands, (band + 1) * h // bands
    return (0, y0, w, y1 - y0)
