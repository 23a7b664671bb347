"""The sun read from a plate's clear sky: a clear sky is brightest around the sun.

A plate rarely shows its sun, yet the sun is most of the light on a person outdoors. A clear sky
gives it away: it is brightest around the sun and darkest some 90 degrees from it, brighter towards
the horizon on the sun's side (the Perez et al. 1993 all-weather sky model, with Preetham et al.
1999's luminance coefficients for a turbidity ``T``). The plate's visible sky is fitted with it:

1. **The sky's pixels** (at ``SKY_WIDTH`` pixels across): above the horizon by ``MIN_ELEVATION``,
   smooth (the log luminance's gradient under ``SMOOTH``), unclipped, at least ``BRIGHT`` of the bright
   sky's level, and joined to the plate's top edge. Their directions are the world's (the camera's
   tilt read from the horizon).
2. **A clear sky**: blue (its median blue over red at least ``BLUE``: Rayleigh scattering; an
   overcast sky, a white wall or a sunset is not), at least ``MIN_SKY`` of the plate, and ending at the
   horizon: the smooth, bright, blue area joined to the top does not run on below it (by more than
   ``RUNS_ON`` of the sky above: a blue wall or backdrop does).
3. **The fit**: every sun direction (``STEP_DEG`` apart, ``MIN_ELEVATION`` to 87 degrees up) and turbidity
   of ``TURBIDITIES``, the log luminance fitted up to a scale; the best refined to a degree. The sun is
   believed where it explains the sky's variation across azimuth: its error at most ``EXPLAINED`` of
   that of the best sky that varies with elevation alone (a quadratic in the zenith angle's cosine)
   seen through a lens darkening towards its corners (a term in the squared distance from the
   picture's middle: a lens's vignetting is no sun's glow); and a sun the fit puts in view must be
   where the plate is clipped (a sun always is). A sun high behind the camera leaves the sky nearly
   the same in every azimuth and is not found.
4. **Its strength**: the open sky's diffuse light on the ground (the fitted sky integrated) times a
   clear day's direct-to-diffuse ratio at the sun's elevation (Meinel's direct normal irradiance over
   Haurwitz's global irradiance less the direct: 6.7 to 9.4 for elevations from 10 to 90
   degrees, 12 at 3), white (the plate's white balance is the sun's). The measured maps' clear sun: 8.7 times (``relight bench plates``).

Measured in ``relight bench plates`` (docs/plates.md): the shared maps' clear-sky park's sun found 8, 9
and 15 degrees off from its three plates (ahead-right, to the left, behind the camera), its person
RMSE 0.209, 0.067, 0.158 where the uniform light's is 0.195, 0.159, 0.382. A sky clipped white, a
sunset, or a sun high behind the camera is not found (the plate's light is then as it was).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from viewer.lighting.envmap import LUMINANCE
from viewer.plate.horizon import horizon_tilt
from viewer.plate.loader import CLIP
from viewer.resize import resize
from viewer.scene.camera import pixel_rays

SKY_WIDTH = 240  # pixels: the plate's width its sky is read at
MIN_ELEVATION = 3.0  # degrees above the horizon: the lowest sky pixel, and the lowest sun
SMOOTH = 0.25  # the log luminance's Sobel gradient at SKY_WIDTH: a sky pixel's is below this
BRIGHT = 0.35  # of the 95th percentile of the luminance above the horizon: a sky pixel is at least this
RUNS_ON = 0.25  # the smooth bright blue area joined to the top, below the horizon, over the sky above it: more, and it is no sky
BLUE = 1.5  # the sky's median blue over red: a clear sky's is at least this
MIN_SKY = 0.02  # of the plate: less sky than this tells nothing of a sun
MIN_SKY_PIXELS = 64  # and fewer sky pixels than this (a tiny plate) neither
EXPLAINED = 0.5  # the sun's fit leaves at most this share of the error of a sky varying with elevation alone
TURBIDITIES = (2.0, 3.0, 5.0, 8.0)
STEP_DEG = 4.0  # degrees between the sun directions tried first
FIT_PIXELS = 800  # sky pixels the fit reads at most (a regular subset)


@dataclass(frozen=True)
class ClearSky:
    """A clear sky read from a plate: its sun at ``sun`` (unit, the level world's frame: x right, y up,
    -z the camera's heading), the Perez sky of ``turbidity`` at ``scale`` (luminance, the plate's linear
    units) in ``colour`` (RGB over luminance); ``irradiance`` the sun's (RGB, on a surface facing it);
    ``pitch`` the camera's tilt up (radians); ``explained`` the fit's error over that of a sky varying
    with elevation alone; ``mask`` (H, W) float32, the plate's sky at ``SKY_WIDTH`` across (its clear
    pixels and the clipped ones beside them)."""

    sun: np.ndarray
    turbidity: float
    scale: float
    colour: np.ndarray
    irradiance: np.ndarray
    pitch: float
    explained: float
    mask: np.ndarray

    @property
    def direction(self) -> np.ndarray:
        """The sun's direction in the plate camera's frame (the map convention of :mod:`viewer.lighting.envmap`)."""
        return camera_direction(self.sun, self.pitch)

    def radiance(self, dirs: np.ndarray) -> np.ndarray:
        """(..., 3) the sky's radiance at ``dirs`` (the camera's frame); below the horizon, the horizon's."""
        world = world_direction(dirs, self.pitch)
        gamma = np.arccos(np.clip(world @ self.sun, -1.0, 1.0))
        lum = self.scale * perez(np.maximum(world[..., 1], 0.0), gamma, self.turbidity)
        return (lum[..., None] * self.colour).astype(np.float32)


def perez(cos_theta: np.ndarray, gamma: np.ndarray, turbidity: float) -> np.ndarray:
    """The Perez sky's relative luminance at zenith angle ``theta`` (its cosine) and angle ``gamma`` from
    the sun, with Preetham's coefficients for ``turbidity``."""
    a, b, c, d, e = _coefficients(turbidity)
    return (1.0 + a * np.exp(b / np.maximum(cos_theta, 0.01))) * (1.0 + c * np.exp(d * gamma) + e * np.cos(gamma) ** 2)


def _coefficients(t: float) -> tuple[float, ...]:
    return (0.1787 * t - 1.4630, -0.3554 * t + 0.4275, -0.0227 * t + 5.3251, 0.1206 * t - 2.5771, -0.0670 * t + 0.3703)


def direct_to_diffuse(elevation: float) -> float:
    """A clear day's direct normal irradiance over its diffuse horizontal irradiance with the sun
    ``elevation`` radians up: Meinel's direct (1353 x 0.7^(AM^0.678), Kasten-Young's air mass AM) over
    Haurwitz's global (1098 sin h exp(-0.057 / sin h)) less the direct's share on the ground."""
    h = max(elevation, math.radians(MIN_ELEVATION))
    s = math.sin(h)
    air_mass = 1.0 / (s + 0.50572 * (6.07995 + math.degrees(h)) ** -1.6364)
    direct = 1353.0 * 0.7 ** (air_mass ** 0.678)
    total = 1098.0 * s * math.exp(-0.057 / s)
    return direct / max(total - direct * s, 0.1 * total)


def plate_sky(plate, horizon: float) -> tuple[ClearSky | None, str]:
    """(the clear sky and its sun read from ``plate``'s sky, or None; why, in words). ``horizon``: the
    horizon's height as a fraction of the plate's, from its top (the camera's tilt)."""

    w, h = plate.size
    width = min(SKY_WIDTH, w)
    size = (width, max(round(h * width / w), 1))
    linear = resize(plate.linear, size, "area")
    clipped = resize(plate.srgb, size, "area") >= CLIP
    focal = plate.focal_at(size)
    pitch = horizon_tilt(horizon, size[1], focal)
    world = _world_directions(size, focal, pitch)
    sky, below = _sky_pixels(linear, clipped, world)
    share = float(sky.mean())
    if share < MIN_SKY or int(sky.sum()) < MIN_SKY_PIXELS:
        return None, f"no sun read from the sky: {100 * share:.2f} % of the plate is open sky (at least {100 * MIN_SKY:.0f} % is needed)"
    if below > RUNS_ON * share:
        return None, ("no sun read from the sky: the smooth blue area down from the plate's top runs on below the horizon "
                      "(a wall, a backdrop: not a sky)")
    rgb = linear[sky].astype(np.float64)
    blue = float(np.median(rgb[:, 2] / np.maximum(rgb[:, 0], 1e-6)))
    if blue < BLUE:
        return None, f"no sun read from the sky: it is not a clear blue sky (blue / red {blue:.2f})"
    dirs = world[sky]
    lum = np.maximum(rgb @ LUMINANCE.astype(np.float64), 1e-6)
    v, u = np.mgrid[0:size[1], 0:size[0]]
    r2 = (((u + 0.5) / size[0] - 0.5) * 2.0) ** 2 + (((v + 0.5) / size[1] - 0.5) * 2.0 * size[1] / size[0]) ** 2
    step = max(len(lum) // FIT_PIXELS, 1)  # (r2: the squared distance from the picture's middle, a lens's vignetting)
    dirs, lum, r2 = dirs[::step], lum[::step], r2[sky][::step]
    flat = _flat_error(dirs, lum, r2)
    error, sun, turbidity, scale = _fit(dirs, lum)
    explained = error / max(flat, 1e-12)
    if explained > EXPLAINED:
        accounted = max(100.0 * (1.0 - explained), 0.0)
        return None, (f"no sun read from the sky: no sun explains how it varies (the best accounts for {accounted:.0f} % "
                      f"of what a sky without one leaves; {100 * (1 - EXPLAINED):.0f} % is needed)")
    seen = _in_view(camera_direction(sun, pitch), focal, size)
    if seen is not None and not clipped[seen[1], seen[0]].any():
        return None, "no sun read from the sky: the sun its glow points to is in view, and the plate is not bright there"
    diffuse = scale * _sky_irradiance(sun, turbidity)  # the open sky's luminance on the ground
    elevation = math.asin(float(np.clip(sun[1], -1.0, 1.0)))
    irradiance = np.full(3, direct_to_diffuse(elevation) * diffuse, np.float32)
    colour = (rgb.mean(axis=0) / max(float(rgb.mean(axis=0) @ LUMINANCE), 1e-12)).astype(np.float32)
    # the sky the unseen sphere is filled with where the plate's is: its clear pixels and the clipped ones
    # beside them (the glow about the sun), not only those the fit read
    fill = _joined_to_top(sky | (clipped.any(axis=-1) & (world[..., 1] > 0.0)))
    return (ClearSky(sun, turbidity, scale, colour, irradiance, pitch, round(explained, 3), fill.astype(np.float32)),
            f"a sun read from the clear sky: {math.degrees(elevation):.0f} degrees up, {bearing(sun)} (its glow accounts for "
            f"{100 * (1 - explained):.0f} % of how the sky varies beyond a sky without a sun)")


def bearing(sun: np.ndarray) -> str:
    """Where ``sun`` (world; only its horizontal part counts) is round the camera, in words."""
    azimuth = math.degrees(math.atan2(float(sun[0]), -float(sun[2])))
    if abs(azimuth) < 1.0:
        return "ahead"
    side = "right" if azimuth > 0 else "left"
    return f"{abs(azimuth):.0f} degrees to the {side} of ahead" + (", behind the camera" if abs(azimuth) > 90.0 else "")


def _world_directions(size: tuple[int, int], focal: float, pitch: float) -> np.ndarray:
    """(H, W, 3) unit directions of the pixel centres in the level world's frame (x right, y up, -z the
    camera's heading) of a camera tilted up by ``pitch`` radians."""
    return world_direction(pixel_rays(size, focal), pitch)


def world_direction(dirs: np.ndarray, pitch: float) -> np.ndarray:
    """Directions in the camera's frame (tilted up by ``pitch``) in the level world's."""
    c, s = math.cos(pitch), math.sin(pitch)
    return np.stack([dirs[..., 0], dirs[..., 1] * c - dirs[..., 2] * s, dirs[..., 2] * c + dirs[..., 1] * s], axis=-1)


def camera_direction(world: np.ndarray, pitch: float) -> np.ndarray:
    """A world direction (:func:`_world_directions`) in the camera's frame."""
    return world_direction(np.asarray(world, np.float64), -pitch)


def _in_view(direction: np.ndarray, focal: float, size: tuple[int, int]) -> tuple[int, int] | None:
    """The pixel (x, y) a direction (the camera's frame) is seen at, or None out of view."""
    if direction[2] >= 0.0:
        return None
    x = 0.5 * size[0] + focal * direction[0] / -direction[2]
    y = 0.5 * size[1] - focal * direction[1] / -direction[2]
    return (int(x), int(y)) if 0.0 <= x < size[0] and 0.0 <= y < size[1] else None


def _sky_pixels(linear: np.ndarray, clipped: np.ndarray, world: np.ndarray) -> tuple[np.ndarray, float]:
    """((H, W) bool: the plate's sky as the module says, step 1; the share of the plate the smooth, bright
    and blue area joined to the top covers more than ``MIN_ELEVATION`` below the horizon: a sky ends there)."""
    import cv2

    lum = linear @ LUMINANCE.astype(np.float32)
    log = np.log(np.maximum(lum, 1e-4)).astype(np.float32)
    gradient = np.hypot(cv2.Sobel(log, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(log, cv2.CV_32F, 0, 1, ksize=3))
    above = world[..., 1] > math.sin(math.radians(MIN_ELEVATION))
    if not above.any():
        return above, 0.0
    smooth = (gradient < SMOOTH) & ~clipped.any(axis=-1) & (lum >= BRIGHT * np.percentile(lum[above], 95))
    blue = linear[..., 2] >= BLUE * np.maximum(linear[..., 0], 1e-6)
    below = _joined_to_top(smooth & blue) & (world[..., 1] < -math.sin(math.radians(MIN_ELEVATION)))
    return _joined_to_top(above & smooth), float(below.mean())


def _joined_to_top(mask: np.ndarray) -> np.ndarray:
    """``mask``'s parts that touch its top row."""
    import cv2

    _, labels = cv2.connectedComponents(mask.astype(np.uint8))
    touching = np.unique(labels[0][mask[0]])
    return np.isin(labels, touching[touching > 0])


def _flat_error(dirs: np.ndarray, lum: np.ndarray, r2: np.ndarray) -> float:
    """The mean squared log-luminance error of the best sky varying with elevation alone, seen through a
    lens that darkens towards its corners (a term in ``r2``, the squared distance from the picture's middle)."""
    c = dirs[:, 1]
    basis = np.stack([np.ones_like(c), c, c * c, r2], axis=-1)
    coeffs, *_ = np.linalg.lstsq(basis, np.log(lum), rcond=None)
    return float(np.mean((basis @ coeffs - np.log(lum)) ** 2))


def world_at(azimuth, elevation) -> np.ndarray:
    """(..., 3) unit directions in the level world's frame of ``azimuth`` (radians from the camera's heading, -z,
    towards +x: the right) and ``elevation`` (radians above the horizon)."""
    az, el = np.broadcast_arrays(np.asarray(azimuth, np.float64), np.asarray(elevation, np.float64))
    return np.stack([np.cos(el) * np.sin(az), np.sin(el), -np.cos(el) * np.cos(az)], axis=-1)


def _suns(elevations: np.ndarray, azimuths: np.ndarray) -> np.ndarray:
    """(N, 3) unit directions of every (elevation, azimuth) pair (radians; azimuth from -z towards +x)."""
    el, az = np.meshgrid(elevations, azimuths, indexing="ij")
    return world_at(az.ravel(), el.ravel())


def _errors(dirs: np.ndarray, log_lum: np.ndarray, suns: np.ndarray, turbidity: float) -> tuple[np.ndarray, np.ndarray]:
    """(each sun's mean squared log-luminance error with the scale fitted, that log scale)."""
    gamma = np.arccos(np.clip(suns @ dirs.T, -1.0, 1.0))
    residual = log_lum[None, :] - np.log(np.maximum(perez(dirs[None, :, 1], gamma, turbidity), 1e-9))
    offset = residual.mean(axis=1)
    return np.mean((residual - offset[:, None]) ** 2, axis=1), offset


def _fit(dirs: np.ndarray, lum: np.ndarray) -> tuple[float, np.ndarray, float, float]:
    """(the error, the sun's direction (world), the turbidity, the sky's scale) of the best fit: a
    grid ``STEP_DEG`` apart over the sky above ``MIN_ELEVATION``, then a degree apart around the best."""
    log_lum = np.log(lum)
    step = math.radians(STEP_DEG)
    grid = _suns(np.arange(math.radians(MIN_ELEVATION), math.radians(88.0), step), np.arange(0.0, 2.0 * math.pi, step))
    best = None
    for turbidity in TURBIDITIES:
        errors, offsets = _errors(dirs, log_lum, grid, turbidity)
        i = int(np.argmin(errors))
        if best is None or errors[i] < best[0]:
            best = (float(errors[i]), grid[i], turbidity, float(offsets[i]))
    _, sun, turbidity, _ = best
    el, az = math.asin(float(sun[1])), math.atan2(float(sun[0]), -float(sun[2]))
    fine = np.radians(np.arange(-STEP_DEG, STEP_DEG + 0.5, 1.0))
    near = _suns(np.clip(el + fine, math.radians(MIN_ELEVATION), math.radians(88.0)), az + fine)
    errors, offsets = _errors(dirs, log_lum, near, turbidity)
    i = int(np.argmin(errors))
    return float(errors[i]), near[i], turbidity, math.exp(float(offsets[i]))


def _sky_irradiance(sun: np.ndarray, turbidity: float, rows: int = 24, columns: int = 96) -> float:
    """The irradiance on the ground of the Perez sky of unit scale with its sun at ``sun`` (world)."""
    el = (np.arange(rows) + 0.5) * (0.5 * math.pi / rows)
    az = (np.arange(columns) + 0.5) * (2.0 * math.pi / columns)
    dirs = _suns(el, az)
    gamma = np.arccos(np.clip(dirs @ sun, -1.0, 1.0))
    solid = (np.cos(el)[:, None] * np.ones(columns)).ravel() * (0.5 * math.pi / rows) * (2.0 * math.pi / columns)
    return float(np.sum(perez(dirs[:, 1], gamma, turbidity) * dirs[:, 1] * solid))
