"""The frame passes: the final composite and display at the output frame's resolution.

A scene made from a photo carries a :class:`viewer.scene.bundle.FrameLayer`: the photo's frame at its
own resolution (the detail albedo, the person's soft matte, the photo). The engine does all of
its per-light work (shadow maps, filtering, shading) at the maps' work resolution; the work
composite also writes the two shading sums ``D = sum_l V_l I_l S_diff_l`` and
``S = sum_l V_l I_l S_spec_l``. These passes then bring them to the frame:

1. **frame background** (``shaders/frame_background.frag.glsl``): the background in linear HDR
   at the frame's resolution (the environment map seen through the frame's camera, the photo, a
   colour or nothing), kept in a texture: redrawn only when the background, the map or its
   rotation changes;
2. **frame composite** (``shaders/frame_composite.frag.glsl``): at every frame pixel
   ``HDR = A_frame D + S t`` (alpha = the matte; t the albedo's fine detail, its luminance over
   its mean at the work frame's scale, which the sheen takes), D and S mipmapped after the work composite and
   sampled with ``filled_sample`` (bilinear, normalized by the mask, filled past it, so the
   person's shading never mixes with the empty background at the matte's edge), then over the
   background, exposure, tone map and sRGB: the display image, in the same pass. The same shader
   gives the frame's HDR on request (:meth:`FramePass.read`), for saved EXRs.

Cache rules (each pass's ``inputs``; the engine tracks them): the shading sums' mipmaps after
each work composite; the frame composite over the matte's bounding box when the work composite
is redone, over the whole frame when the look or the view changes; the frame background when
the background, its colour, the map or its rotation does.
"""

from __future__ import annotations

import moderngl
import numpy as np

from viewer.gl.display_pass import set_background
from viewer.gl.kit import PassKit, band_box
from viewer.scene.bundle import FrameLayer
from viewer.scene.camera import Camera
from viewer.scene.look import Look
from viewer.shader_modes import code

MAX_FILL_LOD = 4  # mip levels the frame composite may reach past the mask (16 work pixels)
OUTPUT_DISPLAY, OUTPUT_PERSON_HDR, OUTPUT_COMPOSITED_HDR, OUTPUT_BACKGROUND_DISPLAY, OUTPUT_BACKGROUND_HDR = (
    code("OUTPUT", n) for n in ("display", "person_hdr", "composited_hdr", "background_display", "background_hdr"))
ENVIRONMENT_SCALE = 2  # the map behind the person at half the frame's resolution (FrameBackgroundPass)


def frame_camera(frame: FrameLayer, camera: Camera) -> Camera:
    """The scene's camera at the frame's resolution."""
    return Camera(frame.width, frame.height, camera.focal_mm, camera.sensor_mm, camera.distance)


class FrameBackgroundPass:
    """7. The background at the frame's resolution (environment through the camera, photo, colour,
    transparent), in linear HDR, kept in a texture (:attr:`image`). The environment, redrawn on
    every turn of the lighting, is drawn at 1 / ``ENVIRONMENT_SCALE`` of the frame's resolution and
    sampled bilinearly by the frame composite: a map behind a person is as soft as the photo's own
    background or softer (docs/engine.md), and at 2048 pixels the full-resolution pass cost 52 ms
    of a 263 ms frame on llvmpipe. Owns the photo's and the background's textures."""

    name = "frame_background"
    inputs = ("background", "environment")  # the background mode, its colour, the map or its rotation

    def __init__(self, kit: PassKit, frame: FrameLayer, camera: Camera):
        self.kit = kit
        self.camera = frame_camera(frame, camera)
        size = self.size = (frame.width, frame.height)
        self.photo = kit.texture(size, 4, frame.texels[0], dtype="f2")
        self.full = kit.texture(size, 4, dtype="f4", linear=True)
        small = (max(frame.width // ENVIRONMENT_SCALE, 1), max(frame.height // ENVIRONMENT_SCALE, 1))
        self.small_camera = Camera(small[0], small[1], camera.focal_mm, camera.sensor_mm, camera.distance)
        self.small = kit.texture(small, 4, dtype="f4", linear=True)
        self.fbos = {id(t): kit.ctx.framebuffer(color_attachments=[t]) for t in (self.full, self.small)}
        self.image = self.full  # the texture holding the current background

    def run(self, look: Look, background: str, environment: moderngl.Texture, band: tuple[int, int] | None = None):
        """Draw the background; ``band`` (k, n): only the k-th of n bands of rows (a budgeted frame)."""
        kit = self.kit
        with kit.timed(self.name):
            prog = kit.programs.get("fullscreen.vert.glsl", "frame_background.frag.glsl")
            small = background == "environment"
            self.image = self.small if small else self.full
            fbo = self.fbos[id(self.image)]
            fbo.scissor = None if band is None else band_box(self.image.size, *band)
            fbo.use()
            self.photo.use(0)
            environment.use(1)
            prog["photo"] = 0
            prog["environment"] = 1
            set_background(prog, look, background, self.small_camera if small else self.camera)
            kit.fullscreen(prog)
            fbo.scissor = None

    def release(self):
        for obj in (*self.fbos.values(), self.full, self.small, self.photo):
            obj.release()


class FrameMipmapsPass:
    """The shading sums' mip levels, which filled_sample reads past the mask."""

    name = "frame_mipmaps"
    inputs = ("composite", "view")

    def __init__(self, kit: PassKit):
        self.kit = kit

    def run(self, shading):
        with self.kit.timed(self.name):
            for tex in shading:
                tex.build_mipmaps(0, MAX_FILL_LOD)


class FrameCompositePass:
    """8. At each frame pixel A_frame D + S t over the background, then exposure, tone map and sRGB:
    the display image (or, on request, the frame's HDR). Owns the frame's albedo and matte and the
    display image."""

    name = "frame_composite"
    inputs = ("composite", "skin", "skin_scatter")  # redrawn over the matte's box only
    whole_inputs = ("display", "view", "environment", "ground", "ground_shadow")  # redrawn over the whole frame

    def __init__(self, kit: PassKit, frame: FrameLayer, photo: moderngl.Texture, ground: moderngl.Texture, work_width: int,
                 skin=None):
        self.kit, self.photo = kit, photo  # the photo (FrameBackgroundPass's): the "before" of look.compare
        self.ground = ground  # GroundShadowPass's: the background's darkening by the person's shadow
        size = self.size = (frame.width, frame.height)
        self.albedo_alpha = kit.texture(size, 4, frame.texels[1], dtype="f2")
        # the albedo's mean luminance over the person at the work frame's scale: the sheen's detail
        inside = (frame.alpha > 0).astype(np.float32)
        luminance = frame.albedo @ np.array([0.2126, 0.7152, 0.0722], np.float32)
        self.albedo_mean = kit.texture(size, 2, np.dstack([luminance * inside, inside]).astype(np.float16).tobytes(), dtype="f2")
        self.albedo_mean.build_mipmaps()
        self.albedo_mean.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        self.sheen_lod = max(float(np.log2(frame.width / max(work_width, 1))) + 1.0, 0.0)
        self.image = kit.texture(size, 4, dtype="f1")
        self.fbo = kit.ctx.framebuffer(color_attachments=[self.image])
        self.back = self.back_fbo = None  # the image drawn in bands while the front is shown (made when first needed)
        self.box = frame.box
        self.skin = skin  # the SkinScatterPass whose image replaces D on the skin when shown (None: no skin)

    def run(self, shading, background: moderngl.Texture, terms, look: Look, mode: str, box=None):
        with self.kit.timed(self.name):
            self.draw(self.fbo, shading, background, terms, look, mode, OUTPUT_DISPLAY, box)

    def draw_band(self, shading, background: moderngl.Texture, terms, look: Look, mode: str, band: int, bands: int):
        """Band ``band`` of ``bands`` (rows) of the display image, into the back image (:meth:`swap`)."""
        if self.back is None:
            self.back = self.kit.texture(self.size, 4, dtype="f1")
            self.back_fbo = self.kit.ctx.framebuffer(color_attachments=[self.back])
        with self.kit.timed(self.name):
            self.draw(self.back_fbo, shading, background, terms, look, mode, OUTPUT_DISPLAY,
                      band_box(self.size, band, bands))

    def swap(self):
        """The back image, all its bands drawn, becomes the one shown."""
        self.image, self.back = self.back, self.image
        self.fbo, self.back_fbo = self.back_fbo, self.fbo

    def draw(self, fbo: moderngl.Framebuffer, shading, background: moderngl.Texture, terms, look: Look, mode: str,
             output_mode: int = OUTPUT_DISPLAY, box=None, sheen_detail: bool = True):
        """The frame composite into ``fbo``: the display image (``output_mode`` 0) over ``box``
        (None: the whole frame), or one of the HDR outputs; ``mode`` the background shown (the
        look's, resolved to what the scene has); ``sheen_detail`` False: the sheen as the work frame
        sums it (the photo's own, which inference takes out), without the albedo's fine detail."""
        kit = self.kit
        prog = kit.programs.get("fullscreen.vert.glsl", "frame_composite.frag.glsl")
        fbo.scissor = box
        fbo.use()
        self.albedo_alpha.use(0)
        shading[0].use(1)
        shading[1].use(2)
        background.use(3)
        self.photo.use(4)
        self.ground.use(5)
        self.albedo_mean.use(8)
        prog["albedo_mean"] = 8
        prog["sheen_detail"] = sheen_detail
        prog["ground_occlusion"] = 5
        prog["ground"] = look.ground
        scattered = self.skin is not None and self.skin.shown
        (self.skin.image if scattered else self.photo).use(6)  # textures bound either way
        (self.skin.skin if scattered else self.photo).use(7)
        prog["skin_scattered"] = 6
        prog["skin"] = 7
        prog["skin_scatter"] = scattered
        prog["skin_box"] = self.skin.box if scattered else (0, 0, 0, 0)
        prog["skin_box_to_uv"] = self.skin.box_to_uv if scattered else (0.0, 0.0)
        prog["frame_albedo_alpha"] = 0
        prog["sheen_lod"] = self.sheen_lod
        prog["shading_diffuse"] = 1
        prog["shading_specular"] = 2
        prog["background"] = 3
        prog["photo"] = 4
        prog["compare_x"] = look.compare * self.size[0] if output_mode == OUTPUT_DISPLAY else 0.0
        prog["frame_to_uv"] = (1.0 / self.size[0], 1.0 / self.size[1])
        prog["max_lod"] = MAX_FILL_LOD
        diffuse, specular, unit_albedo = terms
        prog["term_weights"] = (diffuse, specular)
        prog["unit_albedo"] = unit_albedo
        prog["transparent"] = mode == "transparent"
        prog["photo_background"] = mode == "photo"
        prog["exposure"] = look.exposure_stops
        prog["tonemap_op"] = code("TONEMAP", look.tonemap)
        prog["output_mode"] = output_mode
        kit.fullscreen(prog)
        fbo.scissor = None

    def read(self, shading, background, terms, look: Look, mode: str, output_mode: int,
             sheen_detail: bool = True) -> np.ndarray:
        """(H, W, 4) float32: the person's HDR and matte (``OUTPUT_PERSON_HDR``), the HDR over
        the background (``OUTPUT_COMPOSITED_HDR``) or the display of the background alone
        (``OUTPUT_BACKGROUND_DISPLAY``, in [0, 1]), drawn into a texture made for the call
        (``sheen_detail``: :meth:`draw`)."""
        with self.kit.scratch_target(self.size) as (tex, fbo):
            self.draw(fbo, shading, background, terms, look, mode, output_mode, sheen_detail=sheen_detail)
            return self.kit.read(tex, 4)

    def release(self):
        for obj in (self.fbo, self.image, self.back_fbo, self.back, self.albedo_alpha, self.albedo_mean):
            if obj is not None:
                obj.release()
