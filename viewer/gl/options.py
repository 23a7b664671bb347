"""The engine's quality options (what a preset chooses, viewer/gl/presets.py), validated on creation."""

from __future__ import annotations

from dataclasses import dataclass

from viewer.errors import InputError
from viewer.gl.prefilter import METHODS
from viewer.gl.soft import soft_method_names
from viewer.scene.shadow_space import PCSS_MIN_TEXELS


@dataclass(frozen=True)
class EngineOptions:
    shadow_resolution: int = 512  # texels of each light's shadow map
    shadow_step: int = 0  # depth-mesh decimation for shadow passes (1 = every pixel; 0 = auto,
    # 3 per 512 image pixels: ~1.5 cm triangles on the sample, 1.8 % error, see docs/engine.md)
    terms: int = 4  # CSM Fourier terms M (2M basis maps)
    prefilter: str = "pyramid"  # "pyramid" (cost independent of sigma) or "exact"
    soft: str = "pcss"  # soft shadows, a method of viewer/gl/soft/: "pcss" (contact-hardening: the penumbra grows with the blocker-receiver
    # distance, shaders/pcss.glsl; lower error than CSM and hard shadows, docs/results/results.md) or "csm" (the paper's
    # convolutional shadow maps with ``terms`` and ``prefilter``)
    hard_sigma: float = 0.05  # sigma (256-px units) below which soft visibility = hard visibility
    pcss_min_texels: float = PCSS_MIN_TEXELS  # with soft "pcss": the penumbra's smallest sigma, shadow-map texels
    # (0: a sharp shadow's edge steps from texel to texel; relight bench upsample measures both)
    skip_threshold: float = 1e-5  # lights whose upper bound is below this fraction of the diffuse level are skipped
    leave_out: bool = True  # skip what the scene does not need (dark lights, soft filtering at sigma ~ 0, specular
    # work on a matte scene); False does all of it, for measuring what the policy saves (relight bench report)
    profile: bool = False  # finish GL work after every pass and record its wall time
    ground_scale: int = 2  # the ground shadow at 1 / ground_scale of the work resolution or less (at most
    # viewer.gl.ground_pass.GROUND_PIXELS: costly per pixel, every light's visibility and the feet's contact points;
    # the drag preview's levels take 4-8, viewer/app/preview.py)

    def __post_init__(self):
        r = self.shadow_resolution
        if not (isinstance(r, int) and 16 <= r <= 8192 and r & (r - 1) == 0):
            raise InputError(None, f"shadow resolution must be a power of two in [16, 8192], got {r}")
        if not 2 <= self.terms <= 16:
            raise InputError(None, f"CSM terms must be in [2, 16], got {self.terms}")
        if self.shadow_step < 0:
            raise InputError(None, f"shadow step must be >= 0 (0 = auto), got {self.shadow_step}")
        if self.soft not in soft_method_names():
            raise InputError(None, f"soft shadows must be one of {', '.join(soft_method_names())}, got {self.soft!r}")
        if self.prefilter not in METHODS:
            raise InputError(None, f"prefilter must be one of {', '.join(METHODS)}, got {self.prefilter!r}")
        if not (self.hard_sigma >= 0 and 0 <= self.skip_threshold < 1):
            raise InputError(None, "hard_sigma must be >= 0 and skip_threshold in [0, 1)")
        if not (isinstance(self.ground_scale, int) and 1 <= self.ground_scale <= 8):
            raise InputError(None, f"the ground shadow's scale must be an integer in [1, 8], got {self.ground_scale}")
        if not 0 <= self.pcss_min_texels <= 64:
            raise InputError(None, f"the penumbra's smallest sigma must be in [0, 64] texels, got {self.pcss_min_texels}")
