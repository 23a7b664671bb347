"""The frame passes: the final composite and display at the output frame's resolution.

A scene made from a photo carries a :class:`viewer.scene.FrameLayer`: the photo's frame at its
own resolution (the detail albedo, the person's soft matte, the photo). The engine does all of
its per-light work (shadow maps, filtering, shading) at the maps' work resolution; the work
composite also writes the two shading sums ``D = sum_l V_l I_l S_diff_l`` and
``S = sum_l V_l I_l S_spec_l``. These passes then bring them to the frame:

1. **frame background** (``shaders/frame_background.frag.glsl``): the background in linear HDR
   at the frame's resolution (the environment map seen through the frame's camera, the photo, a
   colour or nothing), kept in a texture: redrawn only when the background, the map or its
   rotation changes;
2. **frame composite** (``shaders/frame_composite.frag.glsl``): at every frame pixel
   ``HDR = A_frame D + S`` (alpha = the matte), D and S mipmapped after the work composite and
   sampled with ``filled_sample`` (bilinear, normalized by the mask, filled past it, so the
   person's shading never mixes with the empty background at the matte's edge), then over the
   background, exposure, tone map and sRGB: the display image, in the same pass. The same shader
   gives the frame's HDR on request (:meth:`FramePass.read`), for saved EXRs.

Cache rules (kept by :class:`viewer.gl.engine.Engine`): the frame composite is redone over the
matte's bounding box when the work composite is, over the whole frame when a display setting
changes; the frame background when the background, the map or its rotation does.
"""

from __future__ import annotations

import moderngl
import numpy as np

from ..camera import Camera
from ..scene import FrameLayer

MAX_FILL_LOD = 4  # mip levels the frame composite may reach past the mask (16 work pixels)
OUTPUT_DISPLAY, OUTPUT_PERSON_HDR, OUTPUT_COMPOSITED_HDR = 0, 1, 2


class FramePass:
    """Owns the frame-resolution textures: ``draw_background``, ``draw`` (the display), ``read``."""

    def __init__(self, ctx: moderngl.Context, programs, fullscreen, frame: FrameLayer, camera: Camera, texture):
        self.ctx = ctx
        self.programs = programs
        self._fullscreen = fullscreen
        self._texture = texture
        self.camera = Camera(frame.width, frame.height, camera.focal_mm, camera.sensor_mm, camera.distance)
        size = self.size = (frame.width, frame.height)
        albedo_alpha = np.dstack([frame.albedo, frame.alpha]).astype(np.float16)
        self.tex_albedo_alpha = texture(size, 4, albedo_alpha.tobytes(), dtype="f2")
        photo = np.dstack([frame.photo, np.ones(frame.alpha.shape, np.float32)]).astype(np.float16)
        self.tex_photo = texture(size, 4, photo.tobytes(), dtype="f2")
        self.background = texture(size, 4, dtype="f2")
        self.background_fbo = ctx.framebuffer(color_attachments=[self.background])
        self.display = texture(size, 4, dtype="f1")
        self.display_fbo = ctx.framebuffer(color_attachments=[self.display])
        rows, cols = np.nonzero(frame.alpha > 0)
        self.box = (int(cols.min()), int(rows.min()), int(cols.max() - cols.min() + 1), int(rows.max() - rows.min() + 1)) \
            if rows.size else (0, 0, 1, 1)

    def draw_background(self, state: dict, modes: dict, environment: moderngl.Texture):
        """The background of the display state (``background``, ``color``, ``rotation``)."""
        prog = self.programs.get("fullscreen.vert.glsl", "frame_background.frag.glsl")
        self.background_fbo.use()
        self.tex_photo.use(0)
        environment.use(1)
        prog["photo"] = 0
        prog["environment"] = 1
        prog["background_mode"] = modes[state["background"]]
        prog["background_color"] = tuple(float(c) for c in state["color"])
        prog["environment_rotation"].write(np.asarray(state["rotation"], dtype="f4").T.tobytes())
        prog["focal_center_px"] = self.camera.center
        prog["focal_px"] = self.camera.focal_px
        self._fullscreen(prog)

    def draw(self, fbo: moderngl.Framebuffer, shading, terms, state: dict, tonemaps: dict, output_mode: int = OUTPUT_DISPLAY,
             box=None):
        """The frame composite into ``fbo``: the display image (``output_mode`` 0) over ``box``
        (None: the whole frame), or one of the HDR outputs."""
        prog = self.programs.get("fullscreen.vert.glsl", "frame_composite.frag.glsl")
        fbo.scissor = box
        fbo.use()
        self.tex_albedo_alpha.use(0)
        shading[0].use(1)
        shading[1].use(2)
        self.background.use(3)
        prog["frame_albedo_alpha"] = 0
        prog["shading_diffuse"] = 1
        prog["shading_specular"] = 2
        prog["background"] = 3
        prog["frame_to_uv"] = (1.0 / self.size[0], 1.0 / self.size[1])
        prog["max_lod"] = MAX_FILL_LOD
        diffuse, specular, unit_albedo = terms
        prog["term_weights"] = (diffuse, specular)
        prog["unit_albedo"] = unit_albedo
        prog["transparent"] = state["background"] == "transparent"
        prog["exposure"] = float(state["exposure"])
        prog["tonemap_op"] = tonemaps[state["tonemap"]]
        prog["output_mode"] = output_mode
        self._fullscreen(prog)
        fbo.scissor = None

    def read(self, shading, terms, state: dict, tonemaps: dict, output_mode: int) -> np.ndarray:
        """(H, W, 4) float32: the person's HDR and matte (``OUTPUT_PERSON_HDR``) or the HDR over
        the background (``OUTPUT_COMPOSITED_HDR``), drawn into a texture made for the call."""
        tex = self._texture(self.size, 4)
        fbo = self.ctx.framebuffer(color_attachments=[tex])
        try:
            self.draw(fbo, shading, terms, state, tonemaps, output_mode)
            w, h = self.size
            return np.frombuffer(tex.read(), np.float32).reshape(h, w, 4).copy()
        finally:
            fbo.release()
            tex.release()

    def release(self):
        for obj in (self.background_fbo, self.background, self.display_fbo, self.display, self.tex_albedo_alpha,
                    self.tex_photo):
            obj.release()
