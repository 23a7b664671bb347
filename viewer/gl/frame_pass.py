"""The frame passes: the final composite and display at the output frame's resolution.

A scene made from a photo carries a :class:`viewer.scene.FrameLayer`: the photo's frame at its
own resolution (the detail albedo, the person's soft matte, the photo). The engine does all of
its per-light work (shadow maps, filtering, shading) at the maps' work resolution; the work
composite also writes the two shading sums ``D = sum_l V_l I_l S_diff_l`` and
``S = sum_l V_l I_l S_spec_l``. These passes then bring them to the frame:

1. **frame composite** (``shaders/frame_composite.frag.glsl``): ``HDR = A_frame D + S`` at every
   frame pixel, alpha = the matte. D and S are mipmapped after the work composite and sampled
   with ``filled_sample`` (bilinear, normalized by the mask, filled past it), so the person's
   shading never mixes with the empty background at the matte's edge.
2. **frame display** (``shaders/display.frag.glsl``, shared with the work display): exposure,
   tone map, sRGB over the background: the environment map seen through the frame's camera, the
   frame's photo, a colour, or transparent.

Cache rules (kept by :class:`viewer.gl.engine.Engine`): the frame composite is redone when the
work composite is; the frame display when either is, or when a display setting changes. A
change of the foreground only (lights, shadows) redraws the matte's bounding box of the display.
"""

from __future__ import annotations

import moderngl
import numpy as np

from ..camera import Camera
from ..scene import FrameLayer

MAX_FILL_LOD = 4  # mip levels the frame composite may reach past the mask (16 work pixels)


class FramePass:
    """Owns the frame-resolution textures; ``composite`` then ``display``."""

    def __init__(self, ctx: moderngl.Context, programs, fullscreen, frame: FrameLayer, camera: Camera, texture):
        self.ctx = ctx
        self.programs = programs
        self._fullscreen = fullscreen
        self.camera = Camera(frame.width, frame.height, camera.focal_mm, camera.sensor_mm, camera.distance)
        size = (frame.width, frame.height)
        self.size = size
        albedo_alpha = np.dstack([frame.albedo, frame.alpha]).astype(np.float16)
        self.tex_albedo_alpha = texture(size, 4, albedo_alpha.tobytes(), dtype="f2")
        photo = np.dstack([frame.photo, np.ones(frame.alpha.shape, np.float32)]).astype(np.float16)
        self.tex_photo = texture(size, 4, photo.tobytes(), dtype="f2")
        self.hdr = texture(size, 4)
        self.hdr_fbo = ctx.framebuffer(color_attachments=[self.hdr])
        self.hdr_fbo.clear(0.0, 0.0, 0.0, 0.0)
        self.display = texture(size, 4, dtype="f1")
        self.display_fbo = ctx.framebuffer(color_attachments=[self.display])
        rows, cols = np.nonzero(frame.alpha > 0)
        self.box = (int(cols.min()), int(rows.min()), int(cols.max() - cols.min() + 1), int(rows.max() - rows.min() + 1)) \
            if rows.size else (0, 0, 1, 1)

    def composite(self, shading_diffuse: moderngl.Texture, shading_specular: moderngl.Texture, terms):
        """Frame HDR from the work composite's shading sums (mipmapped by the caller)."""
        prog = self.programs.get("fullscreen.vert.glsl", "frame_composite.frag.glsl")
        fbo = self.hdr_fbo
        fbo.scissor = self.box  # outside the matte's box the frame HDR stays cleared
        fbo.use()
        self.tex_albedo_alpha.use(0)
        shading_diffuse.use(1)
        shading_specular.use(2)
        prog["frame_albedo_alpha"] = 0
        prog["shading_diffuse"] = 1
        prog["shading_specular"] = 2
        prog["frame_to_uv"] = (1.0 / self.size[0], 1.0 / self.size[1])
        prog["max_lod"] = MAX_FILL_LOD
        diffuse, specular, unit_albedo = terms
        prog["term_weights"] = (diffuse, specular)
        prog["unit_albedo"] = unit_albedo
        self._fullscreen(prog)
        fbo.scissor = None

    def release(self):
        for obj in (self.hdr_fbo, self.hdr, self.display_fbo, self.display, self.tex_albedo_alpha, self.tex_photo):
            obj.release()
