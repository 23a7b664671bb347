"""Procedural environment maps for training variety (the nine CC0 maps stay held out):

- ``sky``: a clear sky (a blue zenith fading to a paler horizon) over a ground of random colour,
  with a sun of random angular size, elevation, azimuth, colour and brightness (sun to sky ratios
  from 10 to 1e5, the stiff case);
- ``studio``: a dark room with two to four soft rectangular emitters (key, fill, rim) of random
  direction, size, colour temperature and strength;
- ``overcast``: the CIE overcast sky, L(theta) = L_z (1 + 2 cos theta) / 3 above the horizon, over a
  dim ground;
- ``outdoor``: the sky and sun of ``sky`` over a skyline of trees or buildings (a sun that would
  set behind it stands just above it), over a textured ground (grass, earth, paving): the
  cluttered, lit surroundings real photos are taken in;
- ``interior``: a room of four textured walls, a floor and a ceiling, lit by one to three windows
  (bright sky-coloured patches near the horizon) and up to four ceiling lamps.

Not in the training pool: ``key_light``, a held-out lighting kind that spherical harmonics cannot
fake, as a photographer sets it: one small disc light (2-6 degrees across) at 30-80 degrees of
azimuth from the camera and 10-45 degrees up, in black (no fill); in half of them a rim light behind
the person on the other side (``key_rim``). Its maps are made facing the camera and are not turned.

Suns sit low more often than not (elevation 3-75 degrees with a bias to the horizon): low and
backlighting suns are where photos differ most from studio light. Maps turn by a random longitude
in the dataset, so any sun or window is also behind the person in some lightings.

Every map is a function of its seed alone (``numpy.random.default_rng(seed)``), in the project's
frame and units (docs/conventions.md). Emitters are drawn with their exact energy: each texel's
coverage is supersampled (4 x 4), and an emitter smaller than a sub-texel puts its whole energy
into the texel that holds its centre, so a tiny sun keeps its light.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewer.files.imageio import srgb_to_linear
from viewer.lab.data.materials import fbm
from viewer.lighting.envmap import EnvMap, direction_to_uv, pixel_directions, solid_angles

KINDS = ("sky", "studio", "overcast", "outdoor", "interior")
SUPERSAMPLE = 4


@dataclass(frozen=True)
class Emitter:
    """A light in the map: unit ``direction``; ``radius`` (radians) of a disc (sun) or half-size of a
    square patch (studio); RGB ``energy`` (irradiance it gives a surface facing it)."""
    direction: np.ndarray
    radius: float
    energy: np.ndarray
    square: bool = False


@dataclass(frozen=True)
class ProceduralMap:
    env: EnvMap
    kind: str
    emitters: tuple  # the Emitters drawn into it (for tests and the manifest)
    skyline: object = None  # outdoor: the skyline's elevation (radians) as a function of azimuth


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _direction(azimuth: float, elevation: float) -> np.ndarray:
    """Camera-space direction at ``azimuth`` (radians from -z, towards +x) and ``elevation``."""
    return np.array([np.cos(elevation) * np.sin(azimuth), np.sin(elevation), -np.cos(elevation) * np.cos(azimuth)])


def _azimuth(d: np.ndarray) -> np.ndarray:
    """Azimuth (radians from -z, towards +x) of directions (..., 3): :func:`_direction`'s inverse."""
    return np.arctan2(d[..., 0], -d[..., 2])


def _subtexel_directions(h: int, w: int) -> np.ndarray:
    """(h, w, S*S, 3) directions of a regular S x S grid inside every texel: the texel centres of
    the map at S times the resolution, grouped by the texel they fall in."""
    s = SUPERSAMPLE
    return pixel_directions(h * s, w * s).reshape(h, s, w, s, 3).transpose(0, 2, 1, 3, 4).reshape(h, w, s * s, 3)


def _draw(pixels: np.ndarray, e: Emitter, sub: np.ndarray):
    """Add emitter ``e`` to ``pixels`` with its exact energy (module docstring)."""
    h, w = pixels.shape[:2]
    d = _unit(e.direction)
    if e.square:
        # patch axes: a tangent frame of d; inside when both angular offsets are within the half-size
        up = np.array([0.0, 1.0, 0.0]) if abs(d[1]) < 0.99 else np.array([1.0, 0.0, 0.0])
        a = _unit(np.cross(up, d))
        b = np.cross(d, a)
        along = sub @ d
        inside = (along > 0) & (np.abs(np.arctan2(sub @ a, along)) <= e.radius) & (np.abs(np.arctan2(sub @ b, along)) <= e.radius)
    else:
        inside = sub @ d >= np.cos(e.radius)
    coverage = inside.mean(axis=2)  # (h, w)
    omega = solid_angles(h, w)[:, None]
    covered = float((coverage * omega).sum())
    if covered <= 0.0:  # smaller than a sub-texel: all of it into the texel holding the centre
        uv = direction_to_uv(d[None])[0]
        i, j = min(int(uv[1] * h), h - 1), min(int(uv[0] * w) % w, w - 1)
        pixels[i, j] += (e.energy / omega[i, 0]).astype(np.float32)
        return
    pixels += (coverage[..., None] * (e.energy / covered)).astype(np.float32)  # energy exactly e.energy


def _sky_gradient(dirs: np.ndarray, zenith: np.ndarray, horizon: np.ndarray, ground: np.ndarray) -> np.ndarray:
    y = dirs[..., 1:2]
    t = np.clip(y, 0.0, 1.0) ** 0.5
    sky = horizon * (1 - t) + zenith * t
    return np.where(y >= 0, sky, ground).astype(np.float32)


def _temperature_rgb(kelvin: float) -> np.ndarray:
    """Approximate linear RGB of a black body at ``kelvin`` (2000-10000 K), green normalized to 1."""
    t = kelvin / 100.0
    r = 1.0 if t <= 66 else 1.29293618606 * (t - 60) ** -0.1332047592
    g = (0.39008157876 * np.log(t) - 0.63184144378) if t <= 66 else 1.12989086089 * (t - 60) ** -0.0755148492
    b = 1.0 if t >= 66 else (0.0 if t <= 19 else 0.54320678911 * np.log(t - 10) - 1.19625408914)
    lin = srgb_to_linear(np.clip([r, g, b], 0.0, 1.0)).astype(np.float64)
    return lin / max(lin[1], 1e-6)


def _clear_sky(rng: np.random.Generator, dirs: np.ndarray):
    """A clear sky gradient over a plain ground; returns the pixels and the sky's radiance level."""
    level = 10 ** rng.uniform(-0.5, 0.5)  # sky radiance scale
    zenith = level * np.array([0.25, 0.45, 1.0]) * rng.uniform(0.8, 1.2, 3)
    horizon = level * np.array([0.8, 0.9, 1.0]) * rng.uniform(0.9, 1.1, 3)
    ground = level * rng.uniform(0.05, 0.3) * rng.uniform(0.6, 1.0, 3)
    return _sky_gradient(dirs, zenith, horizon, ground), level


def _sun(rng: np.random.Generator, level: float) -> Emitter:
    """A sun of 0.25-8 degrees, 10 to 1e5 times the sky's irradiance, low more often than high."""
    sky_irradiance = float(np.pi * level * 0.6)
    elevation = np.radians(3.0 + 72.0 * rng.uniform() ** 1.7)
    return Emitter(_direction(rng.uniform(-np.pi, np.pi), elevation), np.radians(10 ** rng.uniform(np.log10(0.25), np.log10(8.0))),
                   sky_irradiance * 10 ** rng.uniform(1.0, 5.0) * _temperature_rgb(rng.uniform(3000, 6500)))


def sky(rng: np.random.Generator, width: int = 256) -> ProceduralMap:
    h, w = width // 2, width
    pixels, level = _clear_sky(rng, pixel_directions(h, w))
    sun = _sun(rng, level)
    _draw(pixels, sun, _subtexel_directions(h, w))
    return ProceduralMap(EnvMap(pixels, source=None), "sky", (sun,))


def _texture(dirs: np.ndarray, rng: np.random.Generator, color: np.ndarray, scale: float, contrast: float) -> np.ndarray:
    """A colour ``color`` mottled by noise on the sphere (features of ``scale`` radians)."""
    n = fbm(dirs, scale, int(rng.integers(1 << 30)), octaves=4)
    tint = 1.0 + 0.15 * fbm(dirs, 2.0 * scale, int(rng.integers(1 << 30)), octaves=2)[..., None] * rng.uniform(-1, 1, 3)
    return np.clip(color * tint * (1.0 + contrast * n)[..., None], 0.0, None)


# display (sRGB) colours of the surroundings; each is jittered per map
GROUNDS = ((0.30, 0.40, 0.18), (0.55, 0.50, 0.30), (0.40, 0.30, 0.22), (0.25, 0.25, 0.26), (0.55, 0.53, 0.50), (0.75, 0.68, 0.52))
TREES = ((0.18, 0.28, 0.12), (0.25, 0.35, 0.15), (0.32, 0.32, 0.16), (0.20, 0.24, 0.18))
FACADES = ((0.55, 0.30, 0.22), (0.60, 0.60, 0.58), (0.75, 0.65, 0.50), (0.22, 0.26, 0.32), (0.85, 0.85, 0.82))
FLOORS = ((0.50, 0.35, 0.20), (0.35, 0.24, 0.15), (0.55, 0.55, 0.55), (0.30, 0.30, 0.34), (0.60, 0.50, 0.40))


def _palette(rng: np.random.Generator, colours: tuple) -> np.ndarray:
    """Linear RGB of one of ``colours`` (sRGB), jittered."""
    c = np.array(colours[int(rng.integers(len(colours)))]) * rng.uniform(0.85, 1.15, 3)
    return srgb_to_linear(np.clip(c, 0.0, 1.0)).astype(np.float64)


def _skyline(rng: np.random.Generator):
    """A skyline of rolling tree crowns or blocks of buildings: (its elevation in radians as a
    function of azimuth, its colour)."""
    if rng.uniform() < 0.5:  # trees: smooth, bumpy crowns
        seed, base = int(rng.integers(1 << 30)), np.radians(rng.uniform(10.0, 35.0))

        def trees(azimuth):
            ring = np.stack([np.cos(azimuth), np.sin(azimuth), np.zeros_like(azimuth)], axis=-1)
            return base * np.clip(0.7 + 1.2 * fbm(ring, 0.3, seed, octaves=4), 0.0, None)

        return trees, _palette(rng, TREES)
    edges = np.sort(rng.uniform(-np.pi, np.pi, int(rng.integers(8, 24))))  # buildings: flat roofs
    heights = np.radians(rng.uniform(4.0, 45.0, len(edges)))
    return (lambda azimuth: heights[np.searchsorted(edges, azimuth) % len(edges)]), _palette(rng, FACADES)


def outdoor(rng: np.random.Generator, width: int = 256) -> ProceduralMap:
    h, w = width // 2, width
    dirs = pixel_directions(h, w)
    pixels, level = _clear_sky(rng, dirs)
    elevation = np.arcsin(np.clip(dirs[..., 1], -1.0, 1.0))
    azimuth = _azimuth(dirs)
    lit = level * rng.uniform(0.5, 2.0)  # how brightly the surroundings are lit (sky + sun)
    ground = _texture(dirs, rng, lit * _palette(rng, GROUNDS), rng.uniform(0.03, 0.2), 0.8)
    skyline, colour = _skyline(rng)
    facade = _texture(dirs * np.array([1.0, 3.0, 1.0]), rng, lit * colour, rng.uniform(0.05, 0.25), 0.7)
    below = elevation < skyline(azimuth)
    pixels = np.where((elevation < 0)[..., None], ground, np.where(below[..., None], facade, pixels)).astype(np.float32)
    sun = _sun(rng, level)
    # a sun behind the skyline would still light the person in full: it stands just above it instead
    d = sun.direction
    sun_azimuth = float(_azimuth(d))
    lowest = float(skyline(np.array([sun_azimuth]))[0]) + sun.radius + np.radians(1.0)
    if np.arcsin(d[1]) < lowest:
        sun = Emitter(_direction(sun_azimuth, lowest), sun.radius, sun.energy)
    _draw(pixels, sun, _subtexel_directions(h, w))
    return ProceduralMap(EnvMap(pixels, source=None), "outdoor", (sun,), skyline)


def interior(rng: np.random.Generator, width: int = 256) -> ProceduralMap:
    h, w = width // 2, width
    dirs = pixel_directions(h, w)
    level = 10 ** rng.uniform(-1.5, -0.3)
    wall = srgb_to_linear(np.clip(rng.uniform(0.55, 0.95) * rng.uniform(0.88, 1.05, 3), 0, 1)).astype(np.float64)  # near-neutral paint
    azimuth = _azimuth(dirs) + rng.uniform(0, np.pi / 2)
    shade = rng.uniform(0.5, 1.3, 4)[np.floor(azimuth / (np.pi / 2)).astype(int) % 4]  # four walls, each lit its own way
    walls = _texture(dirs, rng, level * wall, rng.uniform(0.05, 0.3), 0.3) * shade[..., None]
    floor = _texture(dirs, rng, level * _palette(rng, FLOORS), rng.uniform(0.02, 0.1), 0.9)
    ceiling = np.broadcast_to(1.3 * level * wall, dirs.shape)
    y = dirs[..., 1:2]
    pixels = np.where(y < -0.3, floor, np.where(y > 0.6, ceiling, walls)).astype(np.float32)
    sub = _subtexel_directions(h, w)
    emitters = []
    for _ in range(int(rng.integers(1, 4))):  # windows: daylight, near the horizon
        e = Emitter(_direction(rng.uniform(-np.pi, np.pi), np.radians(rng.uniform(0.0, 25.0))), np.radians(rng.uniform(8.0, 25.0)),
                    10 ** rng.uniform(0.3, 1.5) * _temperature_rgb(rng.uniform(5500, 9000)), square=True)
        _draw(pixels, e, sub)
        emitters.append(e)
    for _ in range(int(rng.integers(0, 5))):  # ceiling lamps: small and warm
        e = Emitter(_direction(rng.uniform(-np.pi, np.pi), np.radians(rng.uniform(35.0, 85.0))), np.radians(rng.uniform(1.0, 5.0)),
                    10 ** rng.uniform(-0.5, 1.0) * _temperature_rgb(rng.uniform(2700, 4000)))
        _draw(pixels, e, sub)
        emitters.append(e)
    return ProceduralMap(EnvMap(pixels, source=None), "interior", tuple(emitters))


def studio(rng: np.random.Generator, width: int = 256) -> ProceduralMap:
    h, w = width // 2, width
    dirs = pixel_directions(h, w)
    wall = 10 ** rng.uniform(-2.5, -1.0)
    pixels = _sky_gradient(dirs, np.full(3, wall), np.full(3, wall * 1.2), np.full(3, wall * 0.5))
    sub = _subtexel_directions(h, w)
    emitters = []
    for k in range(int(rng.integers(2, 5))):
        elevation = np.radians(rng.uniform(-10.0, 60.0))
        # key and fill in front of the subject (towards the camera, +z is behind the camera: azimuth ~ pi), rim behind
        azimuth = rng.uniform(np.pi / 2, 3 * np.pi / 2) if k < 2 else rng.uniform(-np.pi / 2, np.pi / 2)
        e = Emitter(_direction(azimuth, elevation), np.radians(rng.uniform(5.0, 20.0)),
                    10 ** rng.uniform(0.0, 1.5) * _temperature_rgb(rng.uniform(2700, 7500)), square=True)
        _draw(pixels, e, sub)
        emitters.append(e)
    return ProceduralMap(EnvMap(pixels, source=None), "studio", tuple(emitters))


def overcast(rng: np.random.Generator, width: int = 256) -> ProceduralMap:
    h, w = width // 2, width
    dirs = pixel_directions(h, w)
    lz = 10 ** rng.uniform(-0.3, 0.7)
    tint = rng.uniform(0.9, 1.1, 3)
    cos_theta = np.clip(dirs[..., 1], 0.0, 1.0)
    sky_l = (lz * (1 + 2 * cos_theta) / 3)[..., None] * tint
    ground = lz * rng.uniform(0.05, 0.2) * rng.uniform(0.6, 1.0, 3)
    pixels = np.where(dirs[..., 1:2] >= 0, sky_l, ground).astype(np.float32)
    return ProceduralMap(EnvMap(pixels, source=None), "overcast", ())


def key_light(rng: np.random.Generator, width: int = 256) -> ProceduralMap:
    """One key light (and a rim light behind, half of the time) in black: module docstring."""
    h, w = width // 2, width
    pixels = np.zeros((h, w, 3), np.float32)
    sub = _subtexel_directions(h, w)
    side = 1.0 if rng.uniform() < 0.5 else -1.0
    # azimuth pi faces the camera: the key stands 30-80 degrees off the camera's axis
    key = Emitter(_direction(np.pi + side * np.radians(rng.uniform(30.0, 80.0)), np.radians(rng.uniform(10.0, 45.0))),
                  np.radians(rng.uniform(1.0, 3.0)), 10 ** rng.uniform(0.0, 1.0) * _temperature_rgb(rng.uniform(3200, 6500)))
    emitters = [key]
    if rng.uniform() < 0.5:  # the rim: behind the person, on the other side
        emitters.append(Emitter(_direction(side * np.radians(rng.uniform(20.0, 50.0)), np.radians(rng.uniform(10.0, 40.0))),
                                np.radians(rng.uniform(1.0, 3.0)), key.energy * rng.uniform(0.5, 1.5)))
    for e in emitters:
        _draw(pixels, e, sub)
    return ProceduralMap(EnvMap(pixels, source=None), "key_rim" if len(emitters) > 1 else "key", tuple(emitters))


def random_map(seed: int, width: int = 256, kinds=KINDS) -> ProceduralMap:
    """A procedural map of a kind drawn from ``kinds``, everything decided by ``seed``."""
    rng = np.random.default_rng([seed, 0x5EED])
    kind = kinds[int(rng.integers(len(kinds)))]
    return {"sky": sky, "studio": studio, "overcast": overcast, "outdoor": outdoor, "interior": interior}[kind](rng, width)
