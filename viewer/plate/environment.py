"""The plate's light as an HDR environment map: what lights a person standing in the plate.

A plate shows a narrow cone of the sphere (its camera's field of view, :class:`viewer.plate.loader.Plate`),
in 8 bits, with its brightest parts clipped. The map is built in the plate camera's frame (the map
convention of :mod:`viewer.lighting.envmap`: the map's centre is what the camera looks at):

1. **Seen**: every direction inside the plate's view takes the plate's linear radiance there (the
   plate shrunk by area to about two pixels a map texel first).
2. **Unseen, in front**: a direction outside the view takes the plate's edge where the line from
   the view's centre towards it leaves the frame (the horizon continues sideways, the top edge's sky
   goes up to the zenith, the ground's lower edge down to the nadir), from the plate blurred by
   ``FILL_BLUR`` of its longer side (what is guessed is kept soft).
3. **Unseen, behind the camera** (where most of the light on a person's front comes from): the front
   mirrored through the image plane (from the blurred plate, as step 2), as Khan et al. (2006) fill the sphere from one photo: a
   street behind the camera looks like the street ahead, a room's far wall like its near one.
   This is the estimate's main guess, and where it fails: a sun or a window behind the camera, or
   a dark wall in front of a bright one, is not in the plate and not in the map. That half gets
   ``BEHIND_GAIN - 1`` times the plate's mean (unclipped) light more, evenly: photos' subjects are lit
   better than their backgrounds (a photographer turns a person to the light; a studio lights the
   person, not the wall). Not where a clear sky is found (step 5): the light behind the camera is then
   its fitted sky and sun. **A sun in view is not mirrored behind the camera**: the mirror
   is of the plate as it shows (not of step 4's guess at its clipped highlights, whose light is kept
   there as an amount, not a place), and the light added behind is even up to the mirror's median
   luminance (``TAPER_FROM``) and less and less above it, none at its brightest (as much in all): added
   evenly on top, the mirrored sun or glow outshone the seen one. Plates with the sun in view and no
   clear sky: the estimate's brightest direction was 118-160 degrees off (behind the camera), now 4-35
   (kiara's clipped dawn, immenstadter, venice's sunset); the bench's 27 plates of maps: the brightest
   direction's median 60.7 to 54.4 degrees, the person RMSE medians 0.779 and 0.835 to 0.804 and 0.835 x
   the uniform and SH lights'. Tapered from the 75th or 90th percentile: 0.801 and 0.793 x uniform, but
   venice's sunset in view again 95-105 degrees off, behind; filled from below (the darkest raised first):
   0.767, but an overcast half behind the camera flattened to one level.
   Measured on twelve real photos (``relight bench plates``: each photo's person put back into their
   own photo, lit by the light read from it without them): without it they came back 1.22 stops too
   dark (median), with it 0.40 (the exposure error's median 1.22 to 0.49 stops, RMSE 40.7 to 27.0
   levels); on the maps' plates the person RMSE went from 0.99 to 0.98 x the uniform light's.
4. **Clipped highlights** (a channel at ``CLIP`` of 255 or above) are at least that bright and
   likely brighter: their radiance is multiplied by ``CLIP_GAIN``.
5. **A clear sky and its sun** read from a clear blue sky (:mod:`viewer.plate.sky`: the Perez
   sky fitted to it, its sun where its glow says, in view or not): the sun drawn as a disc of radius
   ``SUN_RADIUS_DEG``; the unseen sky (where the plate's edge it is filled from is sky) the fitted
   sky, not the mirror. A sun in a sky that is not clear and blue (a sunset, haze, a sky clipped
   white), or high behind the camera (the sky nearly the same all round), or seen only in the
   plate's shadows, is not found. (A first rule,
   the largest compact clipped blob above the horizon given five times the sky's irradiance, took
   windows, lamps and bright clouds for suns and made the estimate worse on every plate where it
   fired: not taken.)

6. **A sun from the plate's people**, where no clear sky gave one: the shadows they cast on the ground
   (:mod:`viewer.plate.shadows`: its direction and elevation), else how they are shaded
   (:mod:`viewer.plate.people_shading`: its azimuth, 30 degrees up taken). They say where the sun is, not how
   strong: ``DOMINANT_SHARE`` of the estimate's light (the least a dominant light holds,
   :mod:`viewer.lighting.dominant`) is gathered into a sun there, drawn as step 5's; the estimate's level stays
   (steps 1-4 judge it). Measured on the seven plates that show people (``relight bench plates``) where they read one: drawn on top at
   the strength their ratios say (the lit ground over the shadowed, a fitted light over the even one), the
   person's RMSE was 1.4-3.7 times the uniform light's; gathering 0.8 of the light, 1.4-3.7; 0.5, 0.85-3.4;
   0.3, 0.62-3.1 (better than the run before the shading's sun on six of the seven).

The map's units are the plate's linear values (a plate's exposure is the person's:
:mod:`viewer.plate` composites in them). Measured against the true maps in ``relight bench plates``
(docs/plates.md).
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from viewer.lighting.dominant import DOMINANT_SHARE
from viewer.lighting.envmap import LUMINANCE, EnvMap, pixel_directions, solid_angles
from viewer.plate.horizon import horizon_tilt, plate_horizon
from viewer.plate.loader import CLIP, Plate
from viewer.plate.sky import plate_sky
from viewer.resize import resize

MAP_HEIGHT = 256  # the estimated map is MAP_HEIGHT x 2 MAP_HEIGHT
CLIP_GAIN = 2.0  # a clipped pixel's radiance is taken as this many times what it shows
FILL_BLUR = 0.05  # of the plate's longer side: the blur of the plate the unseen sphere is filled from
SUN_RADIUS_DEG = 1.5  # the radius of the disc a sun read from the sky is drawn as
BEHIND_GAIN = 2.0  # the light behind the camera: the mirror plus (this - 1) x the plate's mean: a photo's subject is lit better
TAPER_FROM = 50.0  # percentile of the mirror's luminance behind the camera: the light added there is even below it, less above


def plate_light(plate: Plate, height: int = MAP_HEIGHT, horizon: float | None = None) -> tuple[EnvMap, dict]:
    """(the plate's light as an equirectangular map, height x 2 height, in the plate camera's frame;
    a record of how: the focal length and where it came from, the field of view, the share clipped, what
    the sky said of a sun, seconds). ``horizon``: the plate's (a fraction of its height, from its top: the
    camera's tilt, which the sky's fit reads elevations by), else its own (:func:`viewer.plate.horizon.plate_horizon`)."""
    import cv2

    t0 = time.perf_counter()
    w, h = plate.size
    texel = math.pi / height
    across = 2.0 * math.atan(max(w, h) / (2.0 * plate.focal_px))
    size, linear, focal = _shrunk(plate, int(np.clip(round(2.0 * across / texel), 16, max(w, h))))  # ~2 pixels a texel
    clipped = resize((plate.srgb >= CLIP).any(axis=-1).astype(np.float32), size, "area")
    radiance = linear * (1.0 + (CLIP_GAIN - 1.0) * clipped[..., None])
    sigma = FILL_BLUR * max(size)
    blurred = cv2.GaussianBlur(radiance, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)

    dirs = pixel_directions(height, 2 * height)
    seen, x, y = _projected(dirs, focal, size)
    pixels = np.where(seen[..., None], _sample(radiance, x, y), _sample(blurred, x, y))
    horizon = plate_horizon(plate)[0] if horizon is None else horizon
    sky, said = plate_sky(plate, horizon)
    # behind the camera: the mirror of what the plate shows (not of what its clipped highlights are guessed to be),
    # and the light added there (the clip gain's guess, how much and not where; without a clear sky, BEHIND_GAIN - 1
    # times the plate's mean unclipped light) evenly but for its brightest parts: a sun or a glow in view, mirrored
    # with light added on top, would outshine itself behind the camera
    behind = dirs[..., 2] > 0.0
    mirrored = _sample(cv2.GaussianBlur(linear, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE), x, y)
    added = (radiance - linear).reshape(-1, 3).mean(axis=0)
    if sky is None:
        unclipped = clipped < 0.5
        added = added + (BEHIND_GAIN - 1.0) * (linear[unclipped].mean(axis=0) if unclipped.any() else linear.reshape(-1, 3).mean(axis=0))
    solid = np.broadcast_to(solid_angles(height, 2 * height)[:, None], behind.shape)
    pixels[behind] = _added_below_the_brightest(mirrored[behind], solid[behind], added)
    if sky is None:
        sun = _people_sun(plate, horizon)  # no clear sky: the plate's people may say where its sun is
        if sun is not None:  # where it is, not how strong: the least share a dominant light holds
            pixels, said = _gathered(pixels, dirs, sun[0], DOMINANT_SHARE), sun[1]
    else:  # the unseen sky the fitted clear sky, where the plate's edge it is filled from is sky; and its sun
        mask = cv2.GaussianBlur(resize(sky.mask, size, "area"), (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)
        share = np.where(seen, 0.0, _sample(mask, x, y))[..., None]
        pixels = (1.0 - share) * pixels + share * sky.radiance(dirs)
        _draw_sun(pixels, dirs, sky.direction, sky.irradiance)
    pixels = np.maximum(pixels, 0.0).astype(np.float32)
    record = {"focal_35mm": round(plate.focal_35, 2), "focal_from": plate.focal_source,
              "field_of_view_deg": round(math.degrees(across), 2), "clipped_share": round(float(clipped.mean()), 5),
              "sun": said, "seconds": round(time.perf_counter() - t0, 3)}
    return EnvMap(pixels, plate.source), record


def _added_below_the_brightest(values: np.ndarray, solid: np.ndarray, added: np.ndarray) -> np.ndarray:
    """``values`` (N, 3) over texels of ``solid`` angles with light of ``added`` (RGB radiance, were it even) more in
    all: evenly up to the texels' ``TAPER_FROM`` percentile of luminance, then less and less up to none at the brightest (the light
    added keeps the mirror's sky above and ground below, and does not raise its brightest part: a sun or glow in
    view, mirrored, would otherwise outshine itself)."""
    lum = values @ LUMINANCE.astype(np.float32)
    extra = float(added @ LUMINANCE) * float(solid.sum())  # the light to add (luminance over solid angle)
    if extra <= 0.0 or not len(lum):
        return values
    middle, top = float(np.percentile(lum, TAPER_FROM)), float(lum.max())
    share = np.clip((top - lum) / (top - middle), 0.0, 1.0) if top > middle else np.ones_like(lum)
    amount = extra / max(float(np.sum(share * solid)), 1e-12)  # the even level the shares scale
    colour = added / max(float(added @ LUMINANCE), 1e-12)
    return (values + (amount * share)[:, None] * colour[None, :]).astype(np.float32)


def _people_sun(plate: Plate, horizon: float) -> tuple | None:
    """(direction (the plate camera's frame), what was said) of the sun the plate's people say, or None: the
    shadows they cast (:mod:`viewer.plate.shadows`), else their shading (:mod:`viewer.plate.people_shading`:
    its azimuth, ``TYPICAL_ELEVATION`` taken)."""
    from viewer.plate.people_shading import sun_from_shading
    from viewer.plate.shadows import TYPICAL_ELEVATION, sun_from_shadows

    shadow, said = sun_from_shadows(plate, horizon)
    if shadow is not None:
        return shadow.direction, said
    shading, said = sun_from_shading(plate)
    if shading is None:
        return None
    return (shading.direction_at(horizon_tilt(horizon, plate.size[1], plate.focal_px)),
            f"{said}; its elevation not read: {math.degrees(TYPICAL_ELEVATION):.0f} degrees up taken")


def _gathered(pixels: np.ndarray, dirs: np.ndarray, direction: np.ndarray, share: float) -> np.ndarray:
    """The map with ``share`` of its light (its radiance over the sphere) gathered into a sun at ``direction``
    (white: the plate's white balance is its sun's): where the light comes from changes, not how much there is."""
    solid = solid_angles(*pixels.shape[:2])[:, None, None]
    total = float(np.sum(pixels * solid, axis=(0, 1)) @ LUMINANCE)
    out = pixels * (1.0 - share)
    _draw_sun(out, dirs, direction, np.full(3, share * total, np.float32))
    return out


def _draw_sun(pixels: np.ndarray, dirs: np.ndarray, direction: np.ndarray, irradiance: np.ndarray):
    """A sun at ``direction`` (the map's frame) added to the map as a disc of ``SUN_RADIUS_DEG`` (at least a texel)
    holding ``irradiance`` (RGB, on a surface facing it)."""
    h = pixels.shape[0]
    texel = math.pi / h
    radius = max(math.radians(SUN_RADIUS_DEG), texel)
    disc = dirs @ direction >= math.cos(radius)
    if not disc.any():  # a disc narrower than the texels' spacing: the nearest texel
        disc = np.zeros(dirs.shape[:2], bool)
        disc.flat[int(np.argmax(dirs.reshape(-1, 3) @ direction))] = True
    solid = np.broadcast_to(solid_angles(*pixels.shape[:2])[:, None], disc.shape)
    pixels[disc] += irradiance / float(solid[disc].sum())


def _projected(dirs: np.ndarray, focal: float, size: tuple[int, int]):
    """(seen (H, W) bool, plate x, plate y (pixel coordinates, centres at +0.5)) of every map direction:
    a direction behind the camera is mirrored through the image plane first; one outside the view is
    brought back to the frame's edge along the line from its centre (:mod:`viewer.plate.environment`)."""
    w, h = size
    x, y, z = dirs[..., 0], dirs[..., 1], dirs[..., 2]
    depth = np.abs(z)  # mirrored: behind the camera (z > 0) looks like the front
    du, dv = focal * x, -focal * y
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.minimum.reduce([np.where(depth > 0, 1.0 / depth, np.inf),
                                   np.where(du != 0, (0.5 * w) / np.abs(du), np.inf),
                                   np.where(dv != 0, (0.5 * h) / np.abs(dv), np.inf)])
    scale = np.where(np.isfinite(scale), scale, 0.0)
    seen = (z < 0) & (np.abs(du) <= 0.5 * w * depth) & (np.abs(dv) <= 0.5 * h * depth)
    return seen, 0.5 * w + scale * du, 0.5 * h + scale * dv


def _sample(image: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``image`` read bilinearly at pixel coordinates (x, y) (centres at +0.5), its edge repeated."""
    import cv2

    return cv2.remap(image, (x - 0.5).astype(np.float32), (y - 0.5).astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE)


def placed_plate(plate: Plate, height: int = 64) -> EnvMap:
    """The plate's linear pixels on the sphere as :func:`plate_light` places them (seen, edge-filled,
    mirrored) with nothing added: no clip gain, no blur (the SH baseline of ``relight bench plates``)."""
    size, linear, focal = _shrunk(plate, 4 * height)
    _, x, y = _projected(pixel_directions(height, 2 * height), focal, size)
    return EnvMap(np.maximum(_sample(linear, x, y), 0.0), plate.source)


def _shrunk(plate: Plate, longer: int) -> tuple[tuple[int, int], np.ndarray, float]:
    """(its size (w, h), the plate's linear pixels shrunk by area to ``longer`` pixels on its longer side
    (never enlarged), the focal length in those pixels)."""

    w, h = plate.size
    longer = min(longer, max(w, h))
    size = (max(round(w * longer / max(w, h)), 1), max(round(h * longer / max(w, h)), 1))
    return size, resize(plate.linear, size, "area"), plate.focal_at(size)


LIGHT_VERSION = 7  # bump when a change here changes the map a plate gives (its file is made again)


def plate_light_file(plate: Plate, directory, notes: list | None = None, horizon: float | None = None) -> Path:
    """The plate's light (:func:`plate_light`) as an EXR in ``directory``, made once: named by the
    plate's content (its pixels, its focal length, this module's version) so that it opens as any map
    (the viewer fits it, refits it at another count, turns it) and a plate changed by one pixel, or
    read with another focal length or on another ``horizon`` (:func:`plate_light`'s), gets a file of its
    own. Its record (:func:`plate_light`'s) is a JSON beside it, written after it: a map without its
    record is made again. What it says of the sun goes to ``notes``."""
    import hashlib
    import json

    from viewer.files.imageio import write_text
    from viewer.lighting.envmap import save_envmap

    digest = hashlib.sha256(np.asarray(plate.srgb.shape, np.int64).tobytes() + plate.srgb.tobytes()
                            + f"{plate.focal_35:.4f}-{MAP_HEIGHT}-{LIGHT_VERSION}-{horizon!r}".encode()).hexdigest()[:20]
    stem = Path(plate.source).stem if plate.source else "plate"
    path = Path(directory) / f"{stem}-light-{digest}.exr"
    said = None
    if path.is_file():
        try:
            said = json.loads(path.with_suffix(".json").read_text())["sun"]
        except (OSError, ValueError, KeyError, TypeError):
            said = None
    if not isinstance(said, str):
        env, record = plate_light(plate, horizon=horizon)
        save_envmap(path, env)
        write_text(path.with_suffix(".json"), json.dumps(record) + "\n")
        said = record["sun"]
    if notes is not None:
        notes.append(said)
    return path
