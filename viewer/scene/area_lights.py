"""Area lights: the discrete approximation of an environment map (the paper's N_L x 7 tensor).

Each light has a unit ``direction`` (camera space, pointing from the scene towards the light),
a Gaussian ``sigma`` (the convolutional shadow map's blur, in pixels of a 256-pixel shadow map,
as in the paper; 0 gives a hard shadow) and an RGB ``intensity``: a light of intensity I facing a
white Lambertian surface gives it the radiance I / pi.

Lights published with the paper (``als.npy``: float32 N x 7, direction, sigma, RGB) use the
reference code's environment-map frame, in which the map's top row is y = -1 and the pixel at
normalized (u, v) has direction (cos p cos t, sin p, cos p sin t) with t = pi (2u - 1),
p = pi (v - 1/2). The same pixel in this project's frame (:mod:`viewer.lighting.envmap`) is
``PAPER_TO_CAMERA @ d``: x = z_paper, y = -y_paper, z = -x_paper (a reflection: the two frames
differ in handedness, and mapping through the pixel is what keeps a light on the part of the map
it came from). :func:`load_lights` converts ``.npy`` files this way; intensities and sigma need no
conversion (same shading formula, same 256-pixel sigma unit).

JSON form: ``{"format": "relight-lights", "version": 1, "lights": [{"direction": [x, y, z],
"sigma": s, "intensity": [r, g, b]}, ...]}``. :meth:`AreaLights.to_array` gives the paper's N x 7
layout (direction, sigma, RGB).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.files.imageio import MARK, read_json, write_text
from viewer.files.kinds import regular_file

FORMAT = "relight-lights"
VERSION = 1
UNIT_TOLERANCE = 1e-3
PAPER_TO_CAMERA = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [-1.0, 0.0, 0.0]])
MAX_INTENSITY = 1e20  # far above any real light (a sun is ~1e5 in these units), far below float overflow
MAX_LIGHTS = 256  # the engine's light atlas holds them in a few textures; the final preset uses 64
MAX_SIGMA = 256.0  # 256-px units: a Gaussian as wide as a whole 256-texel shadow map; beyond it nothing changes


@dataclass(frozen=True)
class AreaLights:
    direction: np.ndarray  # (N, 3) float32 unit vectors
    sigma: np.ndarray  # (N,) float32 >= 0
    intensity: np.ndarray  # (N, 3) float32 >= 0

    def __post_init__(self):
        object.__setattr__(self, "direction", np.ascontiguousarray(np.asarray(self.direction, dtype=np.float32).reshape(-1, 3)))
        object.__setattr__(self, "sigma", np.ascontiguousarray(np.asarray(self.sigma, dtype=np.float32).reshape(-1)))
        object.__setattr__(self, "intensity", np.ascontiguousarray(np.asarray(self.intensity, dtype=np.float32).reshape(-1, 3)))

    def __len__(self) -> int:
        return int(self.direction.shape[0])

    def validate(self, where=None) -> AreaLights:
        n = len(self)
        if n > MAX_LIGHTS:
            raise InputError(where, f"{n} lights: at most {MAX_LIGHTS} (the presets use 8 to 64)")
        if self.sigma.shape != (n,) or self.intensity.shape != (n, 3):
            raise InputError(where, f"inconsistent light counts: {n} directions, {self.sigma.shape[0]} sigmas, "
                                    f"{self.intensity.shape[0]} intensities")
        for name in ("direction", "sigma", "intensity"):
            arr = getattr(self, name)
            if not np.isfinite(arr).all():
                raise InputError(where, f"light {int(np.argwhere(~np.isfinite(arr.reshape(n, -1)))[0, 0])}: {name} is NaN or Inf")
        lengths = np.linalg.norm(self.direction, axis=1)
        bad = np.abs(lengths - 1.0) > UNIT_TOLERANCE
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(where, f"light {i}: direction {self.direction[i].tolist()} is not a unit vector (length {lengths[i]:.4g})")
        if (self.sigma < 0).any():
            i = int(np.argmax(self.sigma < 0))
            raise InputError(where, f"light {i}: sigma must be >= 0, got {self.sigma[i]:.4g}")
        if (self.sigma > MAX_SIGMA).any():
            i = int(np.argmax(self.sigma > MAX_SIGMA))
            raise InputError(where, f"light {i}: sigma {self.sigma[i]:.4g} is beyond {MAX_SIGMA:g} (a blur wider than the "
                                    "whole shadow map: the light's size cannot grow its shadows any further)")
        if (self.intensity > MAX_INTENSITY).any():
            i = int(np.argmax((self.intensity > MAX_INTENSITY).any(axis=1)))
            raise InputError(where, f"light {i}: intensity {self.intensity[i].tolist()} is implausibly large (> {MAX_INTENSITY:g})")
        if (self.intensity < 0).any():
            i = int(np.argmax((self.intensity < 0).any(axis=1)))
            raise InputError(where, f"light {i}: intensity must be non-negative, got {self.intensity[i].tolist()}")
        return self

    # ----------------------------------------------------------------- transforms
    def rotated(self, yaw_deg: float = 0.0, tilt_deg: float = 0.0) -> AreaLights:
        """Rotate the whole set: ``yaw`` about the vertical (+y) axis, then ``tilt`` about +x."""
        return AreaLights(self.direction @ rotation_matrix(yaw_deg, tilt_deg).T, self.sigma, self.intensity)

    def with_sigma(self, index: int, sigma: float) -> AreaLights:
        s = self.sigma.copy()
        s[index] = sigma
        return AreaLights(self.direction, s, self.intensity)

    def scaled(self, factor) -> AreaLights:
        return AreaLights(self.direction, self.sigma, self.intensity * np.asarray(factor, dtype=np.float32))

    @property
    def brightest(self) -> int:
        """The index of the light with the largest RGB intensity sum."""
        return int(np.argmax(self.intensity.sum(axis=1)))

    def followed_by(self, other: AreaLights) -> AreaLights:
        """These lights, then ``other``'s."""
        return AreaLights(np.concatenate([self.direction, other.direction]), np.concatenate([self.sigma, other.sigma]),
                          np.concatenate([self.intensity, other.intensity]))

    def to_array(self) -> np.ndarray:
        """(N, 7) float32: direction xyz, sigma, RGB intensity (the paper's layout)."""
        return np.concatenate([self.direction, self.sigma[:, None], self.intensity], axis=1).astype(np.float32)

    @staticmethod
    def from_array(arr) -> AreaLights:
        arr = np.asarray(arr, dtype=np.float32)
        if arr.ndim != 2 or arr.shape[1] != 7:
            raise InputError(None, f"area lights must be an N x 7 array, got shape {arr.shape}")
        return AreaLights(arr[:, :3], arr[:, 3], arr[:, 4:7])

    # ----------------------------------------------------------------- files
    def to_json(self) -> dict:
        return {
            "format": FORMAT,
            "version": VERSION,
            "convention": "camera space: x right, y up, z towards the camera; direction points to the light",
            "lights": [
                {"direction": [float(v) for v in d], "sigma": float(s), "intensity": [float(v) for v in i]}
                for d, s, i in zip(self.direction, self.sigma, self.intensity)
            ],
        }

    def save(self, path, fit: dict | None = None) -> Path:
        """Write the JSON light file; ``fit`` (optional) records how the lights were made."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        data = {**self.to_json(), MARK[0]: MARK[1]}
        if fit is not None:
            data["fit"] = fit
        return write_text(path, json.dumps(data, indent=2) + "\n")


def azimuth_elevation(direction) -> tuple[float, float]:
    """Degrees of a direction towards a light (camera space): azimuth about the vertical axis, 0 on
    the camera's side and +90 the image's right; elevation above the horizon."""
    x, y, z = np.asarray(direction, dtype=np.float64) / max(float(np.linalg.norm(direction)), 1e-12)
    return float(np.degrees(np.arctan2(x, z))), float(np.degrees(np.arcsin(np.clip(y, -1.0, 1.0))))


def facing_yaw(lights: AreaLights) -> float:
    """The yaw (degrees, :func:`rotation_matrix`'s) that turns the brightest light to the camera's
    side (azimuth 0: between the person and the viewer), so a first frame is lit from the front.
    0 for lights without intensity or a brightest light straight above or below."""
    if len(lights) == 0 or not np.any(lights.intensity > 0):
        return 0.0
    x, _, z = lights.direction[lights.brightest]
    if abs(x) < 1e-6 and abs(z) < 1e-6:
        return 0.0
    return float(-np.degrees(np.arctan2(x, z)))


def rotation_matrix(yaw_deg: float = 0.0, tilt_deg: float = 0.0) -> np.ndarray:
    """3x3 rotation: yaw about +y (right-handed), then tilt about +x."""
    a, b = np.radians(yaw_deg), np.radians(tilt_deg)
    ry = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    return (rx @ ry).astype(np.float64)


def from_paper_array(arr) -> AreaLights:
    """Lights from the paper's N x 7 array in its environment-map frame (see the module docstring)."""
    lights = AreaLights.from_array(arr)
    direction = lights.direction.astype(np.float64) @ PAPER_TO_CAMERA.T
    return AreaLights(direction, lights.sigma, lights.intensity)


def _check_npy_header(path: Path):
    """The .npy header's shape and dtype checked against the file's size before numpy allocates:
    an N x 7 array of at most MAX_LIGHTS rows whose data the file really holds."""
    from numpy.lib import format as npy

    try:
        with open(path, "rb") as f:
            version = npy.read_magic(f)
            read_header = npy.read_array_header_1_0 if version == (1, 0) else npy.read_array_header_2_0
            shape, _, dtype = read_header(f, max_header_size=10_000)
            data_start = f.tell()
    except (ValueError, OSError, SyntaxError) as exc:
        raise InputError(path, f"cannot read as a numpy array ({exc})") from None
    if len(shape) != 2 or shape[1] != 7 or not 0 < shape[0] <= MAX_LIGHTS:
        raise InputError(path, f"the paper's light files are N x 7 arrays with N in [1, {MAX_LIGHTS}], got shape {shape}")
    if data_start + shape[0] * 7 * dtype.itemsize != path.stat().st_size:
        raise InputError(path, f"says {shape[0]} x 7 {dtype} values but holds {path.stat().st_size - data_start} bytes of data")


def load_lights(path) -> AreaLights:
    """Load a light file (.json, or the paper's .npy) and validate it."""
    path = regular_file(path, "light file")
    if path.suffix.lower() == ".npy":
        _check_npy_header(path)  # before any allocation: a header may claim 1e12 rows
        try:
            arr = np.load(path, allow_pickle=False)
        except (ValueError, OSError) as exc:
            raise InputError(path, f"cannot read as a numpy array ({exc})") from None
        if arr.dtype.kind not in "fiu":
            raise InputError(path, f"the paper's light files hold numbers, got {arr.dtype} values")
        if arr.ndim != 2 or arr.shape[1] != 7 or len(arr) == 0:
            raise InputError(path, f"the paper's light files are N x 7 arrays, got shape {arr.shape}")
        return from_paper_array(arr).validate(path)
    data = read_json(path, "light file")
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError(path, f"not a light file (format should be {FORMAT!r})")
    try:  # (a value beyond float32 becomes Inf, which validate() names: no overflow warning)
        items = data["lights"]
        with np.errstate(over="ignore"):
            d = np.array([it["direction"] for it in items], dtype=np.float32).reshape(-1, 3)
            s = np.array([it["sigma"] for it in items], dtype=np.float32)
            i = np.array([it["intensity"] for it in items], dtype=np.float32).reshape(-1, 3)
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise InputError(path, f"malformed light entry ({exc})") from None
    if len(d) == 0:
        raise InputError(path, "contains no lights")
    return AreaLights(d, s, i).validate(path)
