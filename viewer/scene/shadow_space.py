"""Geometry of the per-light shadow maps and the convolutional shadow map (CSM) constants.

Shared by the GL engine and the torch twin so both compute the same numbers.

Shadow map of a light with unit direction ``l`` (pointing to the light): an orthographic view
along -l. Its square window is centred on the mesh's bounding sphere (centre ``c``, radius ``r``)
and spans 2r in both directions, the same for every light, so that a blur of sigma pixels means the
same world-space width for every light. With an orthonormal frame (right, up, l):

    u = 0.5 + dot(p - c, right) / (2 r)         (shadow-map x in [0, 1])
    v = 0.5 + dot(p - c, up) / (2 r)            (shadow-map y in [0, 1])
    z = (hi - dot(p, l)) / (hi - lo)            (normalised depth, 0 nearest to the light)

where [lo, hi] is the range of dot(p, l) over the mesh, widened so that the mesh occupies
[pad, 1 - pad] with pad = CSM offset + ``DEPTH_MARGIN``. Texels that no triangle covers hold
``empty_depth`` = 1 - pad. This keeps z - d + offset inside the lit plateau of the truncated Fourier
series for every lit receiver, so empty texels never wrap around into shadow.
Sigma is measured in pixels of a 256-pixel shadow map (the paper's convention), so a shadow map of
R pixels blurs by sigma * R / 256 of its own pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache, cached_property

import numpy as np

SIGMA_REFERENCE_RESOLUTION = 256
DEPTH_MARGIN = 0.02
MIN_DEPTH_EXTENT = 0.05  # fraction of the bounding radius: the depth range of a flat mesh
HARD_SHADOW_THRESHOLD = 0.005  # normalised depth, the paper's hard-test threshold
NORMAL_OFFSET_TEXELS = 1.5  # receivers are pushed along their normal by this many texels
SLOPE_BIAS_TEXELS = 1.0  # extra depth bias: texels times tan(angle between normal and light)
MAX_SLOPE = 20.0  # tan of the angle is clamped here (grazing light)
# A light's sigma read as an angle (contact-hardening penumbrae, shaders/pcss.glsl; specular widening,
# shaders/brdf.glsl). The fitted sigma is the blur of the light-fitting scene; the penumbra of a
# light of angular sigma alpha is alpha x the blocker-receiver distance. ANGULAR_SIGMA (radians per
# sigma unit) is a twin study's best factor (1/51.2) times 1.5, the best of the report's x 0.25 to
# x 3 on RMSE with FLIP and the full-geometry truth (docs/engine.md says how both were measured).
ANGULAR_SIGMA = 1.5 / 51.2
PCSS_TAPS = 16  # the penumbra filter's taps
PCSS_SEARCH_TAPS = 8  # the blocker search's (every lit receiver takes them: half the filter's, docs/engine.md)
PCSS_SEARCH = 0.25  # the blocker search covers blocker-receiver distances up to this many shadow-map windows
# The penumbra's sigma is at least this many shadow-map texels: a sharp shadow's edge is filtered over
# about two texels instead of stepping from texel to texel (a staircase that the output frame, several
# pixels per work pixel, shows as blocks; docs/engine.md measures it)
PCSS_MIN_TEXELS = 0.75


@dataclass(frozen=True)
class LightFrame:
    """Maps camera-space points to shadow-map coordinates (u, v, z) for one light."""

    right: np.ndarray
    up: np.ndarray
    direction: np.ndarray
    center: np.ndarray
    radius: float
    lo: float
    hi: float
    empty_depth: float  # normalised depth stored where no triangle covers a texel
    footprint: tuple = (0.0, 0.0, 1.0, 1.0)  # (u0, v0, u1, v1): the mesh's extent in the shadow map

    @cached_property
    def matrix(self) -> np.ndarray:
        """4x4 (row-major) taking homogeneous camera-space points to (u, v, z, 1); made once (the
        shadow-map and light passes read it in every frame). Read only."""
        m = np.zeros((4, 4), dtype=np.float64)
        s = 1.0 / (2.0 * self.radius)
        m[0, :3] = self.right * s
        m[0, 3] = 0.5 - float(np.dot(self.center, self.right)) * s
        m[1, :3] = self.up * s
        m[1, 3] = 0.5 - float(np.dot(self.center, self.up)) * s
        k = 1.0 / (self.hi - self.lo)
        m[2, :3] = -self.direction * k
        m[2, 3] = self.hi * k
        m[3, 3] = 1.0
        m.flags.writeable = False
        return m

    def texel_world(self, resolution: int) -> float:
        """World-space width of one shadow-map texel."""
        return 2.0 * self.radius / resolution

    def depth_scale(self) -> float:
        """Metres per unit of normalised depth."""
        return self.hi - self.lo


def receiver_coordinates(points, normals, frame: LightFrame, resolution: int):
    """Shadow-map coordinates (u, v, d) and the hard-test bias of camera-pixel receivers.

    The receiver is pushed along its normal by NORMAL_OFFSET_TEXELS texels, and the bias grows with
    the slope: HARD_SHADOW_THRESHOLD + SLOPE_BIAS_TEXELS * texel * min(tan(theta), MAX_SLOPE) / depth
    range, theta the angle between the normal and the light. Lit (hard) when d - bias <= z_sm(u, v),
    z_sm read from the texel containing (u, v). This function is the numpy statement of the rule that
    ``shaders/shadow_test.glsl`` and ``viewer/twin`` implement.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    texel = frame.texel_world(resolution)
    q = p + n * (NORMAL_OFFSET_TEXELS * texel)
    m = frame.matrix
    uvd = q @ m[:3, :3].T + m[:3, 3]
    c = np.abs(n @ frame.direction)
    tan = np.minimum(np.sqrt(np.maximum(1.0 - c * c, 0.0)) / np.maximum(c, 1e-6), MAX_SLOPE)
    bias = HARD_SHADOW_THRESHOLD + SLOPE_BIAS_TEXELS * texel * tan / frame.depth_scale()
    return uvd[:, 0], uvd[:, 1], uvd[:, 2], bias


def bounding_sphere(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre and radius of a sphere around (K, 3) points (box centre; not minimal, but stable)."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    c = 0.5 * (lo + hi)
    r = float(np.sqrt(((points - c) ** 2).sum(axis=1).max()))
    return c.astype(np.float64), max(r, 1e-6)


def depth_pad(terms: int) -> float:
    """Normalised depth left free at both ends of a shadow map's range (see module docstring)."""
    return csm_constants(terms)[0] + DEPTH_MARGIN


PROJECTION_BLOCK = 32768  # points per product in projections(): (192 rows, block) float32 is 24 MB


def projections(axes: np.ndarray, points_by_axis: np.ndarray):
    """``axes`` (R, 3) dotted with the points of ``points_by_axis`` (3, K) in float32, as (R, block)
    products a block of points at a time. It runs in every dragged frame over up to millions of
    points: reduced along their contiguous rows, blocks that stay in the cache are 3.5-13 times
    faster than one (K, R) product reduced down its columns."""
    a = np.asarray(axes, dtype=np.float32)
    for start in range(0, points_by_axis.shape[1], PROJECTION_BLOCK):
        yield a @ points_by_axis[:, start:start + PROJECTION_BLOCK]


def projected_range(axes: np.ndarray, points_by_axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least and greatest of each axis's :func:`projections`."""
    lo, hi = np.full(len(axes), np.inf, np.float32), np.full(len(axes), -np.inf, np.float32)
    for proj in projections(axes, points_by_axis):
        np.minimum(lo, proj.min(axis=1), out=lo)
        np.maximum(hi, proj.max(axis=1), out=hi)
    return lo, hi


def light_frames(points: np.ndarray, directions: np.ndarray, resolution: int, terms: int = 4, sphere=None) -> list[LightFrame]:
    """One :class:`LightFrame` per light for the mesh vertices ``points`` (K, 3) and shadow maps of
    ``resolution`` texels; ``sphere`` is their :func:`bounding_sphere` when the caller has it.
    The depth range also covers receivers pushed along their normals (NORMAL_OFFSET_TEXELS)."""
    pad = depth_pad(terms)
    pts = np.asarray(points)
    c, r = sphere if sphere is not None else bounding_sphere(pts.astype(np.float64))
    dirs = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    refs = np.where((np.abs(dirs[:, 1]) < 0.9)[:, None], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0])
    rights = np.cross(refs, dirs)
    rights /= np.linalg.norm(rights, axis=1, keepdims=True)
    ups = np.cross(dirs, rights)
    axes = np.stack([rights, ups, dirs], axis=1)  # (N, 3, 3): right, up, l per light
    lo_all, hi_all = (x.astype(np.float64).reshape(-1, 3) for x in
                      projected_range(axes.reshape(-1, 3), np.ascontiguousarray(pts.T, dtype=np.float32)))
    reach = NORMAL_OFFSET_TEXELS * 2.0 * r / resolution
    frames = []
    for (right, up, l), (u0, v0, lo), (u1, v1, hi) in zip(axes, lo_all, hi_all):
        lo, hi = lo - reach, hi + reach
        extent = max(hi - lo, MIN_DEPTH_EXTENT * r) / (1.0 - 2.0 * pad)
        hi = hi + pad * extent
        cu, cv = float(c @ right), float(c @ up)
        footprint = tuple(float(0.5 + (x - cx) / (2.0 * r)) for x, cx in ((u0, cu), (v0, cv), (u1, cu), (v1, cv)))
        frames.append(LightFrame(right, up, l, c, r, float(hi - extent), float(hi), 1.0 - pad, footprint))
    return frames


def sigma_in_pixels(sigma: float, resolution: int) -> float:
    """A light's sigma (256-px units) in pixels of a shadow map of the given resolution."""
    return float(sigma) * resolution / SIGMA_REFERENCE_RESOLUTION


@cache
def csm_constants(terms: int) -> tuple[float, float]:
    """(offset, clamp) for CSM reconstruction with ``terms`` Fourier terms.

    The truncated series S_M(x) = 2 sum_k sin(c_k x) / c_k, c_k = pi (2k - 1), approximates the step
    H(x) - 1/2 with Gibbs ringing. ``clamp`` is S_M at its first trough after the overshoot (x = 1/M)
    and ``offset`` the first x > 0 where S_M reaches it, so that after clamping to +-clamp and
    rescaling to [0, 1] a receiver at the occluder's own depth is fully lit. For M = 4 this gives the
    reference code's constants (0.0642233, 0.4458709).
    """
    if terms < 2:
        raise ValueError("CSM needs at least two Fourier terms")
    c = csm_frequencies(terms)

    def s(x):
        return float((2.0 * np.sin(c * x) / c).sum())

    clamp = s(1.0 / terms)
    lo, hi = 0.0, 0.5 / terms  # S_M rises monotonically to its overshoot peak at 1/(2M)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if s(mid) < clamp else (lo, mid)
    return 0.5 * (lo + hi), clamp


def csm_frequencies(terms: int) -> np.ndarray:
    """c_k = pi (2k - 1), k = 1 .. terms (float64; callers cast to their precision)."""
    return math.pi * (2 * np.arange(1, terms + 1) - 1)


def csm_empty_basis(empty_depth: float, terms: int) -> np.ndarray:
    """Basis atlas values (tiles, 4) of an empty texel: (cos c_2t z, sin c_2t z, cos c_2t+1 z,
    sin c_2t+1 z) at z = empty_depth, zero for a missing last term (as shaders/csm.glsl packs them)."""
    c = csm_frequencies(terms)
    out = np.zeros(((terms + 1) // 2, 4))
    for k, ck in enumerate(c):
        out[k // 2, 2 * (k % 2):2 * (k % 2) + 2] = (np.cos(ck * empty_depth), np.sin(ck * empty_depth))
    return out


@cache
def pcss_taps(count: int = PCSS_TAPS) -> np.ndarray:
    """(count, 2) offsets of unit Gaussian sigma: a Vogel spiral (golden-angle turns) whose radii
    are the Gaussian's radial quantiles, so ``count`` taps sample the Gaussian evenly."""
    i = np.arange(count) + 0.5
    radius = np.sqrt(-2.0 * np.log(1.0 - i / count))
    angle = i * math.pi * (3.0 - math.sqrt(5.0))
    return np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)
