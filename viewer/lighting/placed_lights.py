"""Lights the user places: key, fill and rim lights in front of, beside and behind the
person, added to the environment map's area lights.

A placed light is fixed to the camera, as a studio light is: turning the map does not move it.
Its fields are what a photographer sets:
- ``azimuth``: degrees about the vertical axis; 0 is on the camera's side, +90 the image's right;
- ``elevation``: degrees above the horizon;
- ``size``: its angular sigma in degrees; it sizes the penumbrae and widens the highlight, as
  ``sigma x ANGULAR_SIGMA`` does for the map's lights;
- ``intensity``: its irradiance at normal incidence, in the map's units. A new light starts at the
  map's :func:`level`; when the map changes, the viewer scales the placed lights by the ratio of
  the two maps' levels (:func:`rescaled`), so a key tuned on a bright map keeps its share of the
  light on a dim one (or keeps its absolute value, when the user asks);
- ``kelvin``: its colour temperature.

A rig is a list of placed lights. It is saved as JSON: ``{"format": "relight-rig", "lights": [...]}``.
:class:`History` keeps the undo and redo stacks of rigs.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.files.imageio import MARK, read_json, write_text
from viewer.lighting.median_cut import LUMINANCE
from viewer.scene.area_lights import AreaLights, azimuth_elevation
from viewer.scene.shadow_space import ANGULAR_SIGMA

FORMAT = "relight-rig"
KELVIN_RANGE = (1000.0, 15000.0)  # where the Planckian locus approximation below holds
MAX_SIZE = 60.0  # degrees of angular sigma: a light a third of the sky wide (sigma ~36, well under MAX_SIGMA)
# linear sRGB from CIE XYZ (D65)
XYZ_TO_RGB = np.array([[3.2404542, -1.5371385, -0.4985314], [-0.9692660, 1.8760108, 0.0415560],
                       [0.0556434, -0.2040259, 1.0572252]])


@dataclass(frozen=True)
class PlacedLight:
    azimuth: float = 45.0
    elevation: float = 30.0
    size: float = 5.0
    intensity: float = 1.0
    kelvin: float = 5600.0

    def __post_init__(self):
        for name, low, high in (("azimuth", -360.0, 360.0), ("elevation", -90.0, 90.0), ("size", 0.0, MAX_SIZE),
                                ("intensity", 0.0, 1e9), ("kelvin", *KELVIN_RANGE)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= float(value) <= high:
                raise InputError(None, f"a placed light's {name} must be a number in [{low:g}, {high:g}], got {value!r}")
            object.__setattr__(self, name, float(value))

    @property
    def direction(self) -> np.ndarray:
        """Unit direction towards the light, camera space (+z towards the viewer, +y up, +x right)."""
        a, e = math.radians(self.azimuth), math.radians(self.elevation)
        return np.array([math.cos(e) * math.sin(a), math.sin(e), math.cos(e) * math.cos(a)])

    @staticmethod
    def aimed(direction, **fields_) -> PlacedLight:
        """A light from the direction towards it (the azimuth and elevation of the light table)."""
        azimuth, elevation = azimuth_elevation(direction)
        return PlacedLight(azimuth=azimuth, elevation=elevation, **fields_)


def kelvin_to_rgb(kelvin: float) -> np.ndarray:
    """Linear sRGB of a black body at ``kelvin``, with luminance 1: Krystek's (1985) rational
    approximation of the Planckian locus in CIE 1960 (u, v), then xy, XYZ and sRGB's primaries.
    Negative channels (the locus leaves the sRGB gamut below ~1900 K) are clipped."""
    t = float(np.clip(kelvin, *KELVIN_RANGE))
    u = (0.860117757 + 1.54118254e-4 * t + 1.28641212e-7 * t * t) / (1.0 + 8.42420235e-4 * t + 7.08145163e-7 * t * t)
    v = (0.317398726 + 4.22806245e-5 * t + 4.20481691e-8 * t * t) / (1.0 - 2.89741816e-5 * t + 1.61456053e-7 * t * t)
    d = 2.0 * u - 8.0 * v + 4.0
    x, y = 3.0 * u / d, 2.0 * v / d
    rgb = np.maximum(XYZ_TO_RGB @ np.array([x / y, 1.0, (1.0 - x - y) / y]), 0.0)
    return rgb / float(rgb @ LUMINANCE)


def to_area_lights(placed) -> AreaLights:
    """The placed lights as area lights (sigma = size / ANGULAR_SIGMA, RGB = intensity x colour)."""
    placed = list(placed)
    if not placed:
        return AreaLights(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))
    return AreaLights(np.stack([p.direction for p in placed]),
                      np.array([math.radians(p.size) / ANGULAR_SIGMA for p in placed]),
                      np.stack([p.intensity * kelvin_to_rgb(p.kelvin) for p in placed]))


def level(map_lights: AreaLights) -> float:
    """A placed light's unit on a map: a quarter of the luminance total of the map's lights (1 for a
    map without light)."""
    total = float((np.asarray(map_lights.intensity, dtype=np.float64) @ LUMINANCE).sum()) if len(map_lights) else 0.0
    return 0.25 * total if total > 0.0 and math.isfinite(total) else 1.0


def rescaled(placed, factor: float) -> tuple[PlacedLight, ...]:
    """The placed lights with their intensities times ``factor`` (kept in the allowed range)."""
    return tuple(PlacedLight(p.azimuth, p.elevation, p.size, float(np.clip(p.intensity * factor, 0.0, 1e9)), p.kelvin)
                 for p in placed)


# where new lights go, in order: front left and right, front above, the two back corners, the sides
SPOTS = ((45.0, 30.0), (-45.0, 30.0), (0.0, 50.0), (150.0, 30.0), (-150.0, 30.0), (90.0, 15.0), (-90.0, 15.0),
         (0.0, 80.0))
MIN_SEPARATION = 25.0  # degrees between a new light and the ones already placed


def free_spot(placed) -> tuple[float, float]:
    """(azimuth, elevation) for a new light: the first of :data:`SPOTS` at least
    ``MIN_SEPARATION`` from every placed light, else the spot farthest from its nearest light."""
    placed = list(placed)
    if not placed:
        return SPOTS[0]
    have = np.stack([p.direction for p in placed])

    def nearest(spot):
        d = PlacedLight(spot[0], spot[1]).direction
        return float(np.degrees(np.arccos(np.clip(have @ d, -1.0, 1.0))).min())

    for spot in SPOTS:
        if nearest(spot) >= MIN_SEPARATION:
            return spot
    return max(SPOTS, key=nearest)


# the classic studio rigs, as fractions of a level (the key light's intensity)
RIGS = {
    "key": (PlacedLight(45.0, 35.0, 5.0, 1.0, 5600.0),),
    "key and fill": (PlacedLight(45.0, 35.0, 5.0, 1.0, 5600.0), PlacedLight(-50.0, 10.0, 15.0, 0.35, 5600.0)),
    "rim": (PlacedLight(160.0, 25.0, 3.0, 1.2, 6500.0),),
    "key and rim": (PlacedLight(45.0, 35.0, 5.0, 1.0, 5600.0), PlacedLight(-155.0, 30.0, 3.0, 1.0, 6500.0)),
    "three-point": (PlacedLight(45.0, 35.0, 5.0, 1.0, 5600.0), PlacedLight(-50.0, 10.0, 15.0, 0.35, 5600.0),
                    PlacedLight(-155.0, 30.0, 3.0, 0.8, 6500.0)),
}


def rig(name: str, level: float) -> tuple[PlacedLight, ...]:
    """The rig ``name`` of :data:`RIGS` with its key light at ``level``."""
    try:
        lights = RIGS[name]
    except KeyError:
        raise InputError(None, f"unknown rig {name!r}; choose one of {', '.join(RIGS)}") from None
    return tuple(PlacedLight(p.azimuth, p.elevation, p.size, p.intensity * level, p.kelvin) for p in lights)


def save_rig(path, placed) -> Path:
    """Write the rig as JSON (atomically)."""
    return write_text(path, json.dumps({"format": FORMAT, "lights": [asdict(p) for p in placed], MARK[0]: MARK[1]}, indent=2) + "\n")


def load_rig(path) -> tuple[PlacedLight, ...]:
    """A rig saved by :func:`save_rig`; anything else is one line naming the file."""
    data = read_json(path, "rig")
    if not isinstance(data, dict) or data.get("format") != FORMAT or not isinstance(data.get("lights"), list):
        raise InputError(path, f'not a rig: expected {{"format": "{FORMAT}", "lights": [...]}}')
    known = {f.name for f in fields(PlacedLight)}
    out = []
    for k, item in enumerate(data["lights"]):
        if not isinstance(item, dict) or not set(item) <= known:
            raise InputError(path, f"light {k}: expected an object with {', '.join(sorted(known))}")
        try:
            out.append(PlacedLight(**item))
        except InputError as exc:
            raise InputError(path, f"light {k}: {exc.problem}") from None
    return tuple(out)


class History:
    """Undo and redo over the rigs a session had (each a tuple of placed lights)."""

    def __init__(self, limit: int = 200):
        self.undo_stack: list[tuple] = []
        self.redo_stack: list[tuple] = []
        self.limit = limit

    def record(self, before: tuple):
        """Call before a change: ``before`` is what undo brings back."""
        self.undo_stack.append(before)
        del self.undo_stack[:-self.limit]
        self.redo_stack.clear()

    def undo(self, current: tuple) -> tuple | None:
        if not self.undo_stack:
            return None
        self.redo_stack.append(current)
        return self.undo_stack.pop()

    def redo(self, current: tuple) -> tuple | None:
        if not self.redo_stack:
            return None
        self.undo_stack.append(current)
        return self.redo_stack.pop()

    def rescale(self, factor: float):
        """Every rig kept, its intensities times ``factor`` (the map changed: :func:`rescaled`)."""
        self.undo_stack = [rescaled(r, factor) for r in self.undo_stack]
        self.redo_stack = [rescaled(r, factor) for r in self.redo_stack]
