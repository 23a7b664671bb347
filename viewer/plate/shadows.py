"""The sun read from the shadows the plate's people cast on its ground.

A person standing in sunlight casts a shadow on the ground from their feet, away from the sun, as long
as their height over the tangent of the sun's elevation; the ground beside it is lit by the sun and the
sky, the shadow by the sky alone, so their ratio gives the sun's strength against the sky's whatever the
ground's colour. Each person the plate's models find (:attr:`viewer.plate.loader.Plate.people`:
their segmentation and landmarks) whose feet are seen below the horizon is read so:

1. **The ground's geometry**: the camera's tilt from the plate's horizon, its focal length from its
   EXIF; lengths in camera heights (the ground plane one camera height below). The feet stand where
   lower foot's heel, toe or ankle is (a lunge's front foot); the person is as tall as the segmentation's top says, seen from
   there.
2. **The ground around the feet** is read along ``DIRECTIONS`` directions (a run along one follows the
   dark a direction to either side), from ``START`` to ``REACH``
   of the person's height, in the plate's linear luminance; what any person covers (their segmentation
   grown by ``GROW`` of their height: shoes, hair and the matte's edge) and what lies above the horizon
   or off the plate is not ground.
3. **The shadow**: along each direction, the run of ground darker than ``DARK`` of the ground's median
   that starts at the first ground seen from the feet (within ``NEAR_START`` of their height). The
   shadow's direction is where that run is longest, at least ``MIN_RUN`` of the person's height; it is
   believed when the directions dark for half that run span at most ``MAX_SPREAD`` degrees (a shadow is
   narrow), the opposite direction's run is at most ``OPPOSITE`` of it (a dark patch of ground all round
   is no shadow), the ground ``BESIDE`` of their height to either side of it is lit (a person's shadow is
   as wide as they are: a wall's shade is not), at most ``MAX_DARK_SHARE`` of the ground read is dark, and
   the lit ground is at least
   ``MIN_RATIO`` times as bright as the shadow (a skylight's or a window's soft shadow is not a sun's).
4. **The sun**: opposite the shadow, its elevation the arctangent of the person's height over the
   shadow's length (where the shadow runs off the plate or behind someone, the length seen says the sun is
   at most that high: it is taken at ``TYPICAL_ELEVATION`` if that is lower). The lit ground's median over
   the shadow's is said (``ratio``); :func:`viewer.plate.environment.plate_light` takes the direction only.
People's readings are combined weighted by their shadows' lengths (the azimuth's circular mean, the
median elevation and ratio). A sun straight behind the camera casts the shadow behind the person, where
they hide it: none is read.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from viewer.lighting.envmap import LUMINANCE
from viewer.plate.horizon import horizon_tilt
from viewer.plate.sky import bearing, camera_direction, world_at, world_direction
from viewer.resize import resize

SAMPLE_WIDTH = 640  # pixels: the longer side the plate's luminance is read at
DIRECTIONS = 120  # round the feet, 3 degrees apart
STEPS = 64  # samples along each, from START to REACH
START, REACH = 0.05, 3.0  # of the person's height
GROW = 0.04  # of the person's height in pixels: every person's segmentation grown by this is not ground
DARK = 0.6  # of the ground's median luminance: darker ground is in shadow
NEAR_START = 0.5  # of the person's height: the shadow starts at the first ground seen within this of the feet
MIN_RUN = 0.35  # of the person's height: a shorter dark run is no shadow to read
MAX_SPREAD = 60.0  # degrees: the directions dark for half the longest run span at most this
OPPOSITE = 0.3  # the opposite direction's run over the shadow's, at most
MAX_DARK_SHARE = 0.3  # of the ground read: more of it dark and no shadow can be told from it
BESIDE, BESIDE_LIT = 0.5, 0.6  # of the person's height to either side of a shadow, the ground is lit (this share of it)
MIN_RATIO = 2.0  # the lit ground over the shadow at least: a fainter shadow is a soft light's (a skylight, a window)
FEET = ((27, 29, 31), (28, 30, 32))  # MediaPipe's ankle, heel and toe of each foot
TYPICAL_ELEVATION = math.radians(30.0)  # a sun whose shadow's end is not seen: at most this high (it is at most what is seen says)
MIN_TALL = 0.08  # of the plate's height: a smaller person's shadow is a few pixels


@dataclass(frozen=True)
class ShadowSun:
    """The sun the people's shadows say: ``direction`` (unit, the plate camera's frame), ``elevation`` (radians,
    above the level horizon), ``ratio`` (the lit ground over the shadowed), ``people`` (how many said it)."""

    direction: np.ndarray
    elevation: float
    ratio: float
    people: int


def sun_from_shadows(plate, horizon: float) -> tuple[ShadowSun | None, str]:
    """(the sun the shadows of ``plate``'s people say, or None; why, in words). ``horizon``: the plate's (a
    fraction of its height from its top)."""

    people = plate.people
    if not people:
        return None, "no sun read from shadows: no one found standing in the plate"
    w, h = plate.size
    scale = min(SAMPLE_WIDTH / max(w, h), 1.0)
    size = (max(round(w * scale), 1), max(round(h * scale), 1))
    lum = resize(plate.linear, size, "area") @ LUMINANCE.astype(np.float32)
    focal = plate.focal_at(size)
    pitch = horizon_tilt(horizon, size[1], focal)
    segmentations = [resize(p.segmentation, size, "area") > 0.3 for p in people]
    readings = []
    for person, mask in zip(people, segmentations):
        reading = _person_shadow(person, mask, segmentations, lum, focal, pitch)
        if reading is not None:
            readings.append(reading)
    if not readings:
        return None, f"no sun read from shadows: none clear under the {len(people)} people found in the plate"
    runs = np.array([r[3] for r in readings])
    azimuth = math.atan2(float(np.sum(runs * np.sin([r[0] for r in readings]))), float(np.sum(runs * np.cos([r[0] for r in readings]))))
    elevation = float(np.median([r[1] for r in readings]))
    ratio = float(np.median([r[2] for r in readings]))
    world = world_at(azimuth, elevation)
    direction = camera_direction(world, pitch)
    return (ShadowSun(direction / np.linalg.norm(direction), elevation, ratio, len(readings)),
            f"a sun read from the shadows of {len(readings)} of the plate's people: {math.degrees(elevation):.0f} degrees up, "
            f"{bearing(world)} (the lit ground {ratio:.1f} x the shadowed)")


def _person_shadow(person, mask, everyone, lum, focal, pitch) -> tuple[float, float, float, float] | None:
    """(the sun's azimuth (radians from ahead, to the right), its elevation, the lit ground over the shadow,
    the shadow's length in person heights) the ground round ``person``'s feet says, or None."""
    import cv2

    hgt, wid = lum.shape
    sides = [[person.landmarks[i] for i in side if i in person.landmarks] for side in FEET]
    sides = [side for side in sides if side]
    rows = np.flatnonzero(mask.any(axis=1))
    if not sides or not len(rows):
        return None
    foot = max(sides, key=lambda side: max(p[1] for p in side))  # the lower foot (a lunge's front one): on the ground
    fx = float(np.mean([p[0] for p in foot])) * wid
    fy = float(max(p[1] for p in foot)) * hgt
    top = float(rows[0])
    if fy - top < MIN_TALL * hgt:
        return None
    ground = _ground_point(fx, fy, (wid, hgt), focal, pitch)
    if ground is None:
        return None
    tall = _height(ground, top, fx, (wid, hgt), focal, pitch)
    if tall is None or tall <= 0.0:
        return None
    grow = max(int(round(GROW * (fy - top))), 1)
    blocked = cv2.dilate(np.any(everyone, axis=0).astype(np.uint8), np.ones((2 * grow + 1, 2 * grow + 1), np.uint8)) > 0
    phi = np.arange(DIRECTIONS) * (2.0 * math.pi / DIRECTIONS)
    radii = tall * np.linspace(START, REACH, STEPS)
    points = ground[None, None, :] + radii[None, :, None] * world_at(phi, 0.0)[:, None, :]
    seen, values = _ground_read(points, lum, blocked, focal, pitch)
    if seen.sum() < 0.2 * seen.size:
        return None
    level = float(np.median(values[seen]))
    dark = seen & (values < DARK * level)
    if dark.sum() > MAX_DARK_SHARE * seen.sum() or level <= 0.0:
        return None
    # a direction's run follows the shadow within a step to either side (a long thin shadow leaves a straight line
    # of samples wherever the ground's geometry is a little off)
    wide_dark = dark | np.roll(dark, 1, axis=0) | np.roll(dark, -1, axis=0)
    wide_seen = seen | np.roll(seen, 1, axis=0) | np.roll(seen, -1, axis=0)
    runs, tips = np.zeros(DIRECTIONS), np.zeros(DIRECTIONS, bool)
    for k in range(DIRECTIONS):
        runs[k], tips[k] = _run(wide_seen[k], wide_dark[k], radii, tall)
    best = int(np.argmax(runs))
    if runs[best] < MIN_RUN * tall or runs[(best + DIRECTIONS // 2) % DIRECTIONS] > OPPOSITE * runs[best]:
        return None
    near = runs >= 0.5 * runs[best]
    offsets = (np.arange(DIRECTIONS) - best + DIRECTIONS // 2) % DIRECTIONS - DIRECTIONS // 2  # steps from the best, both ways
    if np.ptp(offsets[near]) * (360.0 / DIRECTIONS) > MAX_SPREAD:
        return None
    weights = np.where(near, runs, 0.0)
    shadow = math.atan2(float(np.sum(weights * np.sin(phi))), float(np.sum(weights * np.cos(phi))))
    if not _narrow(ground, shadow, radii[radii <= runs[best]], tall, lum, blocked, level, focal, pitch):
        return None
    shadowed = values[near][dark[near]]
    lit = values[seen & ~dark]
    if not len(shadowed) or not len(lit):
        return None
    ratio = float(np.median(lit)) / max(float(np.median(shadowed)), 1e-6)
    if ratio < MIN_RATIO:
        return None
    elevation = math.atan2(tall, runs[best])
    if not tips[best]:  # the shadow runs on off the plate or behind someone: the sun is at most that high
        elevation = min(elevation, TYPICAL_ELEVATION)
    return math.atan2(-math.sin(shadow), -math.cos(shadow)), elevation, ratio, runs[best] / tall


def _narrow(ground, shadow: float, radii: np.ndarray, tall: float, lum, blocked, level: float, focal: float, pitch: float) -> bool:
    """Whether the ground ``BESIDE`` of the person's height to either side of the shadow (direction ``shadow``,
    along ``radii``) is lit where it is seen, on each side at ``BESIDE_LIT`` of its samples or more: a person's
    shadow is about their width, a wall's or a tree's shade runs on beside it."""
    along, across = world_at(shadow, 0.0), world_at(shadow + 0.5 * math.pi, 0.0)
    for side in (-1.0, 1.0):
        points = ground[None, :] + radii[:, None] * along[None, :] + side * BESIDE * tall * across[None, :]
        seen, values = _ground_read(points, lum, blocked, focal, pitch)
        if seen.sum() < 3 or (values[seen] >= DARK * level).mean() < BESIDE_LIT:
            return False
    return True


def _ground_read(points: np.ndarray, lum: np.ndarray, blocked: np.ndarray, focal: float, pitch: float):
    """(where the ground is seen at ``points`` (..., 3, the level world's frame): in front of the camera, on the
    plate and not ``blocked`` by anyone; the luminance ``lum`` there (nearest pixel))."""
    hgt, wid = lum.shape
    u, v, ahead = _projected(points, (wid, hgt), focal, pitch)
    ui, vi = np.clip(u, 0, wid - 1).astype(int), np.clip(v, 0, hgt - 1).astype(int)
    return ahead & (u >= 0) & (u < wid) & (v >= 0) & (v < hgt) & ~blocked[vi, ui], lum[vi, ui]


def _run(seen: np.ndarray, dark: np.ndarray, radii: np.ndarray, tall: float) -> tuple[float, bool]:
    """(the length of the dark run from the first ground seen, if that lies within ``NEAR_START`` of the
    person's height, else 0; whether its end is seen lit): one sample's gap is bridged."""
    first = np.flatnonzero(seen)
    if not len(first) or radii[first[0]] > NEAR_START * tall or not dark[first[0]]:
        return 0.0, False
    end, gap = first[0], 0
    for i in range(first[0] + 1, len(radii)):
        if not seen[i]:
            return float(radii[end]), False  # behind someone, or off the plate: its end not seen
        if dark[i]:
            end, gap = i, 0
        else:
            gap += 1
            if gap > 1:
                return float(radii[end]), True
    return float(radii[end]), False


def _ground_point(u: float, v: float, size, focal: float, pitch: float) -> np.ndarray | None:
    """The point of the ground plane (one camera height below, the level world's frame) seen at pixel (u, v)."""
    w, h = size
    d = world_direction(np.array([(u - 0.5 * w) / focal, -(v - 0.5 * h) / focal, -1.0]), pitch)
    if d[1] >= -1e-6:
        return None
    return d / -d[1]


def _height(ground: np.ndarray, top: float, u: float, size, focal: float, pitch: float) -> float | None:
    """How tall (camera heights) a person standing at ``ground`` is whose top is seen at row ``top`` (column ``u``)."""
    w, h = size
    d = world_direction(np.array([(u - 0.5 * w) / focal, -(top - 0.5 * h) / focal, -1.0]), pitch)
    across = math.hypot(float(d[0]), float(d[2]))
    if across <= 1e-9:
        return None
    return float(d[1]) * math.hypot(float(ground[0]), float(ground[2])) / across + 1.0


def _projected(points: np.ndarray, size, focal: float, pitch: float):
    """(u, v, in front of the camera) of world ``points`` (..., 3)."""
    w, h = size
    c = world_direction(points, -pitch)
    ahead = c[..., 2] < -1e-6
    z = np.where(ahead, -c[..., 2], 1.0)
    return 0.5 * w + focal * c[..., 0] / z, 0.5 * h - focal * c[..., 1] / z, ahead
