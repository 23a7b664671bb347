"""Light scattered under the skin (skin_scatter.frag.glsl): a screen-space diffusion of the diffuse
shading sum D over the photo's skin, at the frame's resolution, before the frame composite.

Skin carries light millimetres under its surface, red furthest: a terminator or the edge of a cast
shadow on a face is soft and warm, where a surface that reflects at its surface (the engine's
Lambert term) gives a razor edge. This is the real-time answer of Jimenez et al. 2015 ("Separable
Subsurface Scattering"): the irradiance blurred along x then y by a kernel that is skin's diffusion
profile, in millimetres turned into pixels; the profile is d'Eon and Luebke's fit of a three-layer
skin model as a sum of six Gaussians (GPU Gems 3, ch. 14), whose per-channel weights make red
reach about 2.7 mm (the widest Gaussian's sigma) and blue a tenth of that. It acts on D only (the
specular term is reflected at the surface), on skin only (the frame's skin share,
:mod:`viewer.photo.gloss`, weighs each tap: nothing off the skin changes and no cloth light bleeds
onto skin), and the same for light and dark skin (the albedo that multiplies D after it carries the
melanin). Millimetres become pixels through the frame's ``skin_mm`` (millimetres a frame pixel spans,
from the face's width at inference).

Left out where it cannot show: a frame with no skin, ``Look.skin`` off (``--no-skin``), or a kernel
narrower than ``MIN_PIXELS`` frame pixels (a small person: the scatter is under a pixel).
"""

from __future__ import annotations

import math

import moderngl
import numpy as np

from viewer.gl.frame_pass import MAX_FILL_LOD
from viewer.gl.kit import PassKit
from viewer.scene.bundle import FrameLayer, bounding_box

# d'Eon & Luebke 2007: skin's diffusion profile as Gaussians, (variance in mm^2, RGB weight)
SKIN_PROFILE = ((0.0064, (0.233, 0.455, 0.649)), (0.0484, (0.100, 0.336, 0.344)), (0.187, (0.118, 0.198, 0.0)),
                (0.567, (0.113, 0.007, 0.007)), (1.99, (0.358, 0.004, 0.0)), (7.41, (0.078, 0.0, 0.0)))
TAPS_EACH_SIDE = 6
RANGE_SIGMAS = 3.0  # the kernel reaches this many of the widest Gaussian's sigmas
MIN_PIXELS = 0.5  # the widest sigma in frame pixels below which the scatter is left out
CELL_SIGMAS = 1.0  # the scatter's grid: cells of this many widest sigmas, rounded up (1 to 4 frame pixels)


def scatter_kernel(taps_each_side: int = TAPS_EACH_SIDE) -> tuple[np.ndarray, np.ndarray]:
    """(offsets (2T+1,) mm, weights (2T+1, 3)): the profile along one axis, taps denser near the
    centre (offsets grow as the square of the tap's index), each tap weighing the profile's mass
    between the midpoints to its neighbours, so each channel sums to 1 and the sub-pixel
    Gaussians fall on the centre tap."""
    reach = RANGE_SIGMAS * math.sqrt(max(v for v, _ in SKIN_PROFILE))
    u = np.linspace(-1.0, 1.0, 2 * taps_each_side + 1)
    offsets = reach * np.sign(u) * u ** 2
    edges = np.concatenate([[-np.inf], 0.5 * (offsets[1:] + offsets[:-1]), [np.inf]])
    cdf = np.vectorize(lambda x, s: 0.5 * (1.0 + math.erf(x / (s * math.sqrt(2.0)))))
    weights = np.zeros((len(offsets), 3))
    for variance, rgb in SKIN_PROFILE:
        mass = cdf(edges[1:], math.sqrt(variance)) - cdf(edges[:-1], math.sqrt(variance))
        weights += mass[:, None] * np.array(rgb)[None]
    return offsets.astype(np.float32), (weights / weights.sum(axis=0, keepdims=True)).astype(np.float32)


def scatter_reach_px(frame: FrameLayer) -> float:
    """The widest Gaussian's sigma in frame pixels (0 without a skin scale)."""
    return math.sqrt(max(v for v, _ in SKIN_PROFILE)) / frame.skin_mm if frame.skin_mm > 0 else 0.0


class SkinScatterPass:
    """Owns the frame's skin share (a texture) and the scattered irradiance over the skin's box."""

    name = "skin_scatter"
    inputs = ("frame_mipmaps", "skin")  # the shading sums (with their mip levels) and the switch

    def __init__(self, kit: PassKit, frame: FrameLayer):
        self.kit = kit
        self.frame_size = (frame.width, frame.height)
        self.px_per_mm = 1.0 / frame.skin_mm
        self.box = bounding_box(frame.skin > 0)
        self.grid = float(np.clip(np.ceil(CELL_SIGMAS * scatter_reach_px(frame)), 1, 4))
        size = tuple(max(int(np.ceil(n / self.grid)), 1) for n in self.box[2:])
        # 8 bits, as the bundle stores it: a quarter of the upload on the thread that opens a photo
        share = np.ascontiguousarray(np.round(np.clip(frame.skin, 0.0, 1.0) * 255.0).astype(np.uint8))
        self.skin = kit.texture(self.frame_size, 1, share.tobytes(), dtype="f1", linear=True)
        # (D scattered x skin, skin) over the box: the first axis, then both (read bilinearly by the frame composite)
        self.across = kit.texture(size, 4, linear=True)
        self.image = kit.texture(size, 4, linear=True)
        self.fbos = [kit.ctx.framebuffer(color_attachments=[t]) for t in (self.across, self.image)]
        self.box_to_uv = (1.0 / (self.image.size[0] * self.grid), 1.0 / (self.image.size[1] * self.grid))
        self.offsets, self.weights = scatter_kernel()
        self.shown = False  # the image holds the scattered irradiance of the current shading

    @staticmethod
    def applies(frame: FrameLayer | None) -> bool:
        """Whether a frame has skin wide enough in pixels to scatter over."""
        return (frame is not None and frame.skin is not None and bool((frame.skin > 0).any())
                and scatter_reach_px(frame) >= MIN_PIXELS)

    def run(self, shading_diffuse: moderngl.Texture, on: bool):
        """Scatter D (``on``), or mark the image unused (the frame composite then reads D as it is)."""
        self.shown = on
        if not on:
            return
        kit = self.kit
        with kit.timed(self.name):
            for first, (fbo, source) in zip((True, False), ((self.fbos[0], shading_diffuse), (self.fbos[1], self.across))):
                defines = {"SCATTER_TAPS": len(self.offsets)}
                if first:
                    defines["FIRST_AXIS"] = None
                prog = kit.programs.get("fullscreen.vert.glsl", "skin_scatter.frag.glsl", **defines)
                fbo.use()
                source.use(0)
                self.skin.use(1)
                prog["source"] = 0
                prog["skin"] = 1
                prog["box_origin"] = self.box[:2]
                prog["grid"] = self.grid
                prog["frame_to_uv"] = (1.0 / self.frame_size[0], 1.0 / self.frame_size[1])
                if not first:
                    prog["box_to_uv"] = self.box_to_uv
                prog["axis"] = (1.0, 0.0) if first else (0.0, 1.0)
                prog["px_per_mm"] = self.px_per_mm
                prog["offsets_mm"].write(self.offsets.tobytes())
                prog["weights"].write(self.weights.tobytes())
                if first:
                    prog["max_lod"] = MAX_FILL_LOD
                kit.fullscreen(prog)

    def release(self):
        for obj in (*self.fbos, self.across, self.image, self.skin):
            obj.release()
