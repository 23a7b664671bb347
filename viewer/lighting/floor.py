"""A floor laid under a map that shows none: a map with no ground under the feet gets a floor, and the
user is told so (:func:`floor_note`).

A sky-only map (its lower half black) or a studio's black curtain leaves the person standing over
darkness: the backdrop behind the feet is the map below its horizon, and there is nothing there to
stand on. The map's ground is judged by its *albedo as the map lights it*: the mean radiance of the
band seen under the feet (``GROUND_BAND``, degrees below the horizon) over what a white floor would
reflect under the map's sky (its irradiance on an upward-facing plane over pi). Real ground reflects
a few per cent at least (asphalt 5-10 %, the shared maps' grounds 7-47 %, measured with this rule); a
map whose ground reflects under ``NO_GROUND`` shows none. Under it a floor is laid: the rows below
the horizon become a neutral floor of ``FLOOR_ALBEDO`` lit by the same sky (per channel, so a warm sky
gives a warm floor), from the horizon down (blending it into the map's rows below the horizon blended it
with their black: a dark band along the horizon; the backdrop's blur softens the edge). The floor is the
backdrop's only: the lights fitted to the map stay the map's (no light bounces off the floor laid), and
the person's shadow falls on it as on any ground (the ground pass). The map's file is never changed.
"""

from __future__ import annotations

import numpy as np

from viewer.lighting.envmap import LUMINANCE

NO_GROUND = 0.01  # a ground reflecting less than this of its sky's light is none
FLOOR_ALBEDO = 0.18  # the floor laid: a neutral grey
GROUND_BAND = (5.0, 60.0)  # degrees below the horizon: where the ground under the feet is seen
SAMPLE_WIDTH = 512  # the map is judged on every k-th pixel, k its width over this (a 4k map took 0.25 s a frame)


def _elevations(height: int, step: int = 1) -> np.ndarray:
    """The elevation (degrees, + up) of every ``step``-th row of an equirectangular map ``height`` rows tall."""
    return 90.0 - (np.arange(0, height, step) + 0.5) * 180.0 / height


def _sampled(pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(every k-th pixel of the map, every k-th row's elevation), k = its width over ``SAMPLE_WIDTH``."""
    step = max(1, pixels.shape[1] // SAMPLE_WIDTH)
    return pixels[::step, ::step], _elevations(pixels.shape[0], step)


def sky_light(pixels: np.ndarray) -> np.ndarray:
    """(3,) what a white floor reflects under the map's sky: its irradiance on an upward-facing plane
    from the upper hemisphere, over pi (linear RGB)."""
    sample, el = _sampled(pixels)
    el = np.radians(el)
    up = el > 0
    # a pixel's solid angle: cos(el) dtheta dphi; the plane's cosine: sin(el)
    weight = (np.cos(el) * np.sin(el) * (np.pi / len(el)) * (2 * np.pi / sample.shape[1]))[up]
    rows = np.nan_to_num(sample[up].astype(np.float64), nan=0.0, posinf=0.0).sum(axis=1)  # (rows, 3)
    return (weight[:, None] * rows).sum(axis=0) / np.pi


def ground_share(pixels: np.ndarray) -> float:
    """The map's ground as it reflects its sky's light: the mean luminance seen ``GROUND_BAND`` below
    the horizon (solid-angle weighted) over a white floor's under that sky (0: a black ground; nan: no
    sky light at all)."""
    sample, el = _sampled(pixels)
    band = (el < -GROUND_BAND[0]) & (el > -GROUND_BAND[1])
    weight = np.cos(np.radians(el[band]))
    ground = np.nan_to_num(sample[band].astype(np.float64), nan=0.0, posinf=0.0) @ LUMINANCE  # (rows, w)
    mean = float((weight[:, None] * ground).sum() / max(weight.sum() * sample.shape[1], 1e-12))
    white = float(sky_light(pixels) @ LUMINANCE)
    return mean / white if white > 0 else float("nan")


def laid_floor(pixels: np.ndarray) -> np.ndarray:
    """``pixels`` (H, W, 3) linear RGB as they are, or, when their ground reflects under ``NO_GROUND`` of
    the sky's light, with a floor of ``FLOOR_ALBEDO`` under the horizon (a new array)."""
    share = ground_share(pixels)
    if not share < NO_GROUND:  # (nan: a map with no sky light has nothing to light a floor with)
        return pixels
    out = np.array(pixels, dtype=np.float32)
    out[_elevations(pixels.shape[0]) < 0] = FLOOR_ALBEDO * sky_light(pixels)
    return out


def floor_note(pixels: np.ndarray) -> str | None:
    """One line for the user when :func:`laid_floor` lays a floor under this map, else None."""
    share = ground_share(pixels)
    if not share < NO_GROUND:
        return None
    return (f"the map shows no ground (below its horizon it reflects {100 * share:.1f} % of its sky's light): "
            f"a grey floor ({100 * FLOOR_ALBEDO:.0f} % albedo) lit by its sky is laid there behind the person")
