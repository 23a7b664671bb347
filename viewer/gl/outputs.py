"""Reading the engine's outputs back (``Engine.output``): the display image, the HDR (work and frame
resolution), the frame's shading sums, each light's planes and filtered basis, the ground's shadow.
An object handed the passes and textures it reads when the engine is made, so the engine's own
module is the scheduler alone."""

from __future__ import annotations

import functools

import numpy as np

from viewer.gl.context import make_current
from viewer.gl.kit import PassKit
from viewer.gl.light import PASS_OFF


def in_context(method):
    """Runs a method of an object with a ``ctx`` (the engine, its read-back) with that GL context
    current (see :func:`make_current`)."""

    @functools.wraps(method)
    def run(self, *args, **kwargs):
        make_current(self.ctx)
        return method(self, *args, **kwargs)

    return run


class Readback:
    """The read-back half of the engine's interface (after ``Engine.render``). ``shape``: the
    maps' (H, W); ``lights()`` gives
    the engine's lights, ``picture_inputs()`` what its picture draws from now, and
    ``soft_is_hard(light)`` whether a light's soft visibility is its hard one."""

    def __init__(self, kit: PassKit, picture, composite_pass, ground_pass, atlas, resources, csm_basis_pass, lights,
                 picture_inputs, soft_is_hard):
        self.ctx, self.kit, self.picture = kit.ctx, kit, picture
        self.shape = tuple(resources.positions.size[::-1])  # the maps' (H, W): the scene's textures are theirs
        self.composite_pass, self.ground_pass, self.atlas, self.resources = composite_pass, ground_pass, atlas, resources
        self.csm_basis_pass, self.terms = csm_basis_pass, csm_basis_pass.terms
        self._lights, self._picture_inputs, self._soft_is_hard = lights, picture_inputs, soft_is_hard

    @in_context
    def read_ground_shadow(self) -> np.ndarray:
        """(h, w, 3) float32 at half the maps' resolution: the share of the ground plane's light the
        person takes away (``Look.ground``; zero until the ground is shown)."""
        return self.ground_pass.read()

    @in_context
    def read_hdr(self) -> np.ndarray:
        """(H, W, 3) float32 linear HDR of the person (zero outside), at the output size, row 0 at
        the top."""
        return self.read_hdr_rgba()[..., :3]

    @in_context
    def read_hdr_rgba(self) -> np.ndarray:
        """(H, W, 4): the person's linear HDR and its coverage (the mask, or the frame's matte)."""
        return self.picture.read_person(self._picture_inputs())

    @in_context
    def read_frame_shading(self, sheen_detail: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """The diffuse and specular shading sums (sum_l V_l I_l S_diff_l and sum_l V_l I_l S_spec_l),
        (H, W, 3) each at the output frame's resolution, upsampled exactly as the frame composite
        upsamples them, the specular with the albedo's fine detail as the composite gives it
        (``sheen_detail`` False: without; a scene with a frame layer; after render())."""
        return self.picture.read_shading(self._picture_inputs(), sheen_detail)

    @in_context
    def read_work_hdr(self) -> np.ndarray:
        """(H, W, 3) linear HDR at the maps' (work) resolution."""
        return self.kit.read(self.composite_pass.hdr, 4)[..., :3]

    @in_context
    def read_display(self) -> np.ndarray:
        """(H, W, 3) uint8 sRGB display image."""
        return self.kit.read(self.picture.last.image, 4, dtype="f1")[..., :3]

    @in_context
    def read_display_rgba(self) -> np.ndarray:
        """(H, W, 4) uint8: the display image and its alpha (the coverage for the transparent
        background, 255 otherwise)."""
        return self.kit.read(self.picture.last.image, 4, dtype="f1")

    @in_context
    def read_background_display(self) -> np.ndarray:
        """(H, W, 3) uint8 sRGB: the display image as it would be with no person in the picture (the
        background, its exposure and tone map; no shadow on the ground). A scene with a frame layer."""
        image = self.picture.read_background_display(self._picture_inputs())
        return (np.clip(image[..., :3], 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)

    @in_context
    def read_background_hdr(self) -> np.ndarray:
        """(H, W, 4) float32: :meth:`read_output_hdr` with no person in the picture (nor their shadow on
        the ground). A scene with a frame layer."""
        return self.picture.read_background_hdr(self._picture_inputs())

    @in_context
    def read_output_hdr(self) -> np.ndarray:
        """(H, W, 4) float32: the display image's linear HDR before exposure and tone map, over
        the same background (alpha 1), or premultiplied with its coverage for the transparent
        background: the EXR that goes with the display PNG."""
        return self.picture.read_output(self._picture_inputs())

    @in_context
    def read_light(self, index: int) -> dict:
        """Per-light intermediate outputs (H, W) each: soft and hard visibility, diffuse and
        specular shading per unit intensity. All zero for a skipped light and outside the mask."""
        l = self._lights()[index]
        full = np.zeros((*self.shape, 4), np.float32)
        if l.active and l.pass_mode != PASS_OFF:
            x, y, bw, bh = self.resources.mask_box
            full[y:y + bh, x:x + bw] = self.atlas.read_tile(l)
        return {"visibility_soft": full[..., 0], "visibility_hard": full[..., 1], "diffuse": full[..., 2], "specular": full[..., 3]}

    @in_context
    def read_filtered_basis(self, index: int) -> np.ndarray:
        """A light's pre-filtered CSM basis, (2 M, n, n): cos and sin of c_k z for k = 0 .. M-1, at
        the blur plan's mip level (n = shadow resolution / 2^L). Raises for a light whose soft
        visibility is its hard one (sigma ~ 0) or that contributes nothing."""
        l = self._lights()[index]
        if not l.active or l.filtered is None or l.stale & {"shadow_map", "csm_basis"} or l.plan is None \
                or self._soft_is_hard(l):
            raise ValueError(f"light {index} has no current filtered basis (skipped, or sigma ~ 0)")
        atlas = self.kit.read(l.filtered, 4)  # (n, tiles * n, 4)
        n = atlas.shape[0]
        n_tex = self.csm_basis_pass.n_tex
        tiles = [atlas[:, t * n:(t + 1) * n] for t in range(n_tex)]
        maps = [tile[..., c] for tile in tiles for c in range(4)]
        return np.stack(maps[:2 * self.terms])
