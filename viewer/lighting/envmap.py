"""Environment maps: equirectangular (latitude-longitude) HDR images of the light reaching the subject.

Direction convention (also in docs/conventions.md, "Environment maps"). A map is W x H with W = 2 H;
pixel (row i, column j) has its centre at (u, v) = (j + 0.5, i + 0.5) in pixel units. Its direction
is, in camera space (x right, y up, z towards the camera)::

    longitude  phi = 2 pi u / W - pi        (-pi at the left edge, +pi at the right edge)
    latitude   lam = pi / 2 - pi v / H      (+pi/2 at the top edge: row 0 looks up, +y)
    direction  d   = (cos(lam) sin(phi), sin(lam), -cos(lam) cos(phi))

so the centre of the image looks along -z (what the camera sees behind the subject), the point
u = 3W/4 on the equator looks along +x, u = W/4 along -x, and the left/right edges along +z (behind
the camera). :func:`direction_to_uv` is the inverse and returns *normalized* coordinates
(u / W, v / H) in [0, 1); multiply by (W, H) for pixel units.

A texel spans the longitude interval 2 pi / W and the latitudes between its top and bottom edges;
its exact solid angle is ``(2 pi / W) (cos(pi i / H) - cos(pi (i + 1) / H))`` (:func:`solid_angles`;
the sum over the map is 4 pi). The *energy* of a map is ``sum(L * solid angle)`` per RGB channel:
the irradiance its light gives a small white Lambertian patch facing all of it, the same unit as an
area light's intensity (:mod:`viewer.scene.area_lights`).

Rotating a map by the rotation R of :func:`viewer.scene.area_lights.rotation_matrix` (yaw about +y, then tilt
about +x) gives the map L' with L'(R d) = L(d): its lights are the original lights rotated by R
(:meth:`viewer.scene.area_lights.AreaLights.rotated`).

Pixels are linear RGB, float32, finite and non-negative. ``.hdr`` (Radiance RGBE) files are read and
written with OpenCV, ``.exr`` with :mod:`viewer.files.imageio`. Every failure is an
:class:`~viewer.errors.InputError` naming the file.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.files.imageio import atomic_path, check_pixels, read_exr, write_exr
from viewer.files.kinds import regular_file
from viewer.scene.area_lights import rotation_matrix

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 weights of linear RGB

SUFFIXES = (".hdr", ".exr")


def pixel_directions(h: int, w: int) -> np.ndarray:
    """(h, w, 3) float64 unit direction of every texel centre of a w x h map (module convention)."""
    u, v = np.meshgrid((np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h)
    return uv_to_direction(np.stack([u, v], axis=-1))


def uv_to_direction(uv) -> np.ndarray:
    """(..., 2) normalized map coordinates (u / W, v / H; v from the top) to (..., 3) float64 unit
    directions (the module convention: u = 1/2 looks along -z, the top row is +y)."""
    uv = np.asarray(uv, dtype=np.float64)
    phi = 2.0 * np.pi * uv[..., 0] - np.pi
    lam = 0.5 * np.pi - np.pi * uv[..., 1]
    cl = np.cos(lam)
    return np.stack([cl * np.sin(phi), np.sin(lam), -cl * np.cos(phi)], axis=-1)


def direction_to_uv(dirs) -> np.ndarray:
    """Inverse of :func:`pixel_directions`: (..., 3) directions (any length > 0) to (..., 2) float64
    normalized coordinates (u / W, v / H), u in [0, 1) wrapping around, v in [0, 1] from the top."""
    d = np.asarray(dirs, dtype=np.float64)
    phi = np.arctan2(d[..., 0], -d[..., 2])
    lam = np.arctan2(d[..., 1], np.hypot(d[..., 0], d[..., 2]))
    u = np.mod((phi + np.pi) / (2.0 * np.pi), 1.0)
    v = 0.5 - lam / np.pi
    return np.stack([u, v], axis=-1)


def solid_angles(h: int, w: int) -> np.ndarray:
    """(h,) float64 solid angle of one texel of each row (the same along a row); the map sums to 4 pi.
    Broadcast with ``[:, None]`` for an (h, w) array."""
    edges = np.cos(np.pi * np.arange(h + 1) / h)  # sin(latitude) of the row edges, top to bottom
    return (2.0 * np.pi / w) * (edges[:-1] - edges[1:])


@dataclass(frozen=True)
class EnvMap:
    """An equirectangular environment map. ``pixels``: (H, 2H, 3) float32 linear RGB, finite and
    non-negative (checked on construction); ``source``: the file it came from (named in errors)."""

    pixels: np.ndarray
    source: str | None = None

    def __post_init__(self):
        px = np.ascontiguousarray(np.asarray(self.pixels, dtype=np.float32))
        object.__setattr__(self, "pixels", px)
        if px.ndim != 3 or px.shape[2] != 3:
            raise InputError(self.source, f"an environment map must be H x W x 3 (RGB), got shape {px.shape}")
        h, w = px.shape[:2]
        if h < 1 or w != 2 * h:
            raise InputError(self.source, f"an equirectangular map must have a 2:1 aspect (W = 2 H), got {w}x{h}")
        bad = int((~np.isfinite(px)).any(axis=2).sum())
        if bad:
            raise InputError(self.source, f"{bad} pixel(s) are NaN or Inf (--repair sets them to 0)")
        if (px < 0).any():
            raise InputError(self.source, f"{int((px < 0).any(axis=2).sum())} pixel(s) have negative values")
        if (px > MAX_RADIANCE).any():
            raise InputError(self.source, f"{int((px > MAX_RADIANCE).any(axis=2).sum())} pixel(s) are above {MAX_RADIANCE:g}, "
                                          "brighter than any sky (a sun is about 1e5 in these units)")

    @property
    def height(self) -> int:
        return int(self.pixels.shape[0])

    @property
    def width(self) -> int:
        return int(self.pixels.shape[1])

    def energy(self) -> np.ndarray:
        """(3,) float64: sum of L * solid angle over the map, per RGB channel."""
        omega = solid_angles(self.height, self.width)
        return np.einsum("ijc,i->c", self.pixels.astype(np.float64), omega)

    def rotated(self, yaw_deg: float = 0.0, tilt_deg: float = 0.0) -> EnvMap:
        """The map rotated by R = ``rotation_matrix(yaw_deg, tilt_deg)``: the radiance arriving from
        R d is the original's from d. Resampled with bilinear lookups (wrapping in longitude, clamped
        at the poles); a pure yaw by a whole number of texels is an exact column shift."""
        h, w = self.height, self.width
        shift = yaw_deg / 360.0 * w
        if tilt_deg == 0.0 and abs(shift - round(shift)) < 1e-9:
            # yaw by a maps longitude phi to phi - a, so L'(phi) = L(phi + a): column j takes column j + shift
            return EnvMap(np.roll(self.pixels, -int(round(shift)), axis=1), self.source)
        r = rotation_matrix(yaw_deg, tilt_deg)
        src = pixel_directions(h, w) @ r  # row-vector form of R^T d
        return EnvMap(_bilinear(self.pixels, direction_to_uv(src)), self.source)

    def seen_through(self, camera, yaw_deg: float = 0.0, tilt_deg: float = 0.0, ground_squash: float = 1.0) -> np.ndarray:
        """(H, W, 3) float32: the map turned by (yaw, tilt) as the camera sees it behind the person, its
        ground seen from the camera's height (``Look.ground_squash``: 1, as taken) (bilinear; the display
        shader's environment background, ``shaders/display.frag.glsl``, ``envmap.glsl: ground_projected``)."""
        d = camera.view_directions() @ rotation_matrix(yaw_deg, tilt_deg)
        if ground_squash != 1.0:
            d[..., 1] = np.where(d[..., 1] < 0.0, d[..., 1] * ground_squash, d[..., 1])
            d /= np.linalg.norm(d, axis=-1, keepdims=True)
        return _bilinear(self.pixels, direction_to_uv(d))

    def downsampled(self, max_width: int) -> EnvMap:
        """The map area-averaged to width ``2 * (max_width // 2)`` (unchanged if already no wider).

        Each new texel is the solid-angle weighted mean of the old texels it overlaps (exact
        fractional overlaps, any size ratio), so ``energy()`` is preserved to float rounding."""
        if max_width < 2:
            raise InputError(self.source, f"cannot downsample an environment map to width {max_width} (< 2)")
        h2 = max_width // 2
        if self.width <= 2 * h2:
            return self
        h, w = self.height, self.width
        w2 = 2 * h2
        # overlap measures: rows in sin(latitude), columns in longitude; their product is solid angle
        rows = _overlaps(np.cos(np.pi * np.arange(h2 + 1) / h2), np.cos(np.pi * np.arange(h + 1) / h))
        cols = _overlaps(-2.0 * np.pi * np.arange(w2 + 1) / w2, -2.0 * np.pi * np.arange(w + 1) / w)
        omega = rows.sum(axis=1)[:, None] * cols.sum(axis=1)[None, :]
        # each new row reads the few old rows it overlaps, in float64, one row at a time: a 16k map
        # took 3.2 GB and 20 s as one dense product, now its own size and ~1 s
        from scipy import sparse

        cols = sparse.csr_matrix(cols)
        out = np.empty((h2, w2, 3), np.float32)
        for k in range(h2):
            lo, hi = np.flatnonzero(rows[k])[[0, -1]]
            band = np.einsum("i,ijc->jc", rows[k, lo:hi + 1], self.pixels[lo:hi + 1], dtype=np.float64)
            out[k] = (cols @ band) / omega[k][:, None]
        return EnvMap(out, self.source)


def _overlaps(out_edges: np.ndarray, in_edges: np.ndarray) -> np.ndarray:
    """(len(out) - 1, len(in) - 1) lengths of the overlaps of two partitions of one interval, each
    given by its decreasing edges."""
    top = np.minimum(out_edges[:-1, None], in_edges[None, :-1])
    bottom = np.maximum(out_edges[1:, None], in_edges[None, 1:])
    return np.clip(top - bottom, 0.0, None)


def _bilinear(pixels: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup of (H, W, C) ``pixels`` at normalized (..., 2) ``uv`` (wrap in u, clamp in v)."""
    h, w = pixels.shape[:2]
    x = uv[..., 0] * w - 0.5
    y = np.clip(uv[..., 1] * h - 0.5, 0.0, h - 1.0)
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    j0 = np.mod(x0.astype(np.int64), w)
    j1 = np.mod(j0 + 1, w)
    i0 = y0.astype(np.int64)
    i1 = np.minimum(i0 + 1, h - 1)
    top = pixels[i0, j0] * (1 - fx) + pixels[i0, j1] * fx
    bottom = pixels[i1, j0] * (1 - fx) + pixels[i1, j1] * fx
    return (top * (1 - fy) + bottom * fy).astype(np.float32)


MAX_RADIANCE = 1e12  # far above a sun (~1e5), far below float32 overflow once summed over a map
MAX_MAP_WIDTH = 16384
MAX_MAP_PIXELS = MAX_MAP_WIDTH * MAX_MAP_WIDTH // 2  # 1.6 GB of float32 RGB


MAX_RGBE_HEADER = 16 * 1024 * 1024  # comments and tool lines; a longer "header" is not a map


def _rgbe_header(path: Path) -> tuple[int, int, bytes]:
    """(width, height, the file as OpenCV is given it) from a Radiance header, read before any pixel
    (a hostile header cannot make the reader allocate what it claims). The header is read line by
    line up to its blank line, as long as it is (tools write history and comments there), up to
    ``MAX_RGBE_HEADER``; OpenCV is handed the signature, the format line, the resolution line and
    the pixels (its reader split lines at 127 bytes and took a split's end for the header's)."""
    try:
        with open(path, "rb") as f:
            if not f.readline(64).startswith(b"#?"):
                raise InputError(path, "not a Radiance HDR image (no #? signature)")
            fmt = b""
            while f.tell() <= MAX_RGBE_HEADER:
                line = f.readline(MAX_RGBE_HEADER)
                if line in (b"", b"\n"):
                    break
                if line.startswith(b"FORMAT="):
                    fmt = line
            else:
                raise InputError(path, f"not a Radiance HDR image (no end of header in its first "
                                       f"{MAX_RGBE_HEADER // (1024 * 1024)} MB)")
            resolution = f.readline(256) if line == b"\n" else b""
            pixels = f.read() if resolution.endswith(b"\n") else b""
    except OSError as exc:
        raise InputError(path, f"cannot read the map ({exc.strerror or exc})") from None
    try:
        y_tag, height, x_tag, width = resolution.split()[:4]
        if y_tag.lstrip(b"+-") != b"Y" or x_tag.lstrip(b"+-") != b"X":
            raise ValueError
        return int(width), int(height), b"#?RADIANCE\n" + fmt + b"\n" + resolution + pixels
    except (ValueError, IndexError):
        raise InputError(path, "not a Radiance HDR image (no resolution line after the header)") from None


NEGATIVE_SHARE = 0.01  # of a map's pixels: negative values on at most this many are a filter's ringing, set to 0


def load_envmap(path, repair: bool = False) -> EnvMap:
    """Read a ``.hdr`` or ``.exr`` equirectangular map and validate it (see :class:`EnvMap`).

    NaN/Inf pixels are an error unless ``repair`` is set: then they become 0 and a warning names the
    file and the number of pixels replaced. Negative values on at most ``NEGATIVE_SHARE`` of the pixels (the ringing
    that resampling filters leave round a sun) become 0, with a warning; more are refused (not a map of light).
    A one-channel EXR is taken as grey; alpha is dropped."""
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise InputError(path, f"unsupported environment map format {path.suffix!r} (use .hdr or .exr)")
    regular_file(path, "environment map")
    if path.suffix.lower() == ".exr":
        px = read_exr(path, MAX_MAP_PIXELS)
        if px.ndim == 2:
            px = np.repeat(px[..., None], 3, axis=2)
        elif px.shape[2] == 4:
            px = px[..., :3]
    else:
        import cv2

        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)  # failures are ours to say, in one line
        width, height, data = _rgbe_header(path)
        check_pixels(path, width, height, MAX_MAP_PIXELS)
        try:  # the bytes read by Python: OpenCV's own open crashed on a name that is not UTF-8
            bgr = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
        except cv2.error as exc:
            raise InputError(path, f"cannot read as a Radiance HDR image ({str(exc).strip().splitlines()[-1][:120]})") from None
        if bgr is None or bgr.ndim != 3 or bgr.shape[2] != 3 or bgr.dtype != np.float32:
            raise InputError(path, "cannot read as a Radiance HDR image")
        px = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB, dst=bgr)  # in place: a 16k map is 1.6 GB
    px = np.ascontiguousarray(px, dtype=np.float32)
    if repair:
        bad = ~np.isfinite(px)
        count = int(bad.any(axis=2).sum())
        if count:
            px[bad] = 0.0
            warnings.warn(f"{path}: replaced {count} NaN/Inf pixel(s) with 0", stacklevel=2)
    with np.errstate(invalid="ignore"):
        negative = (px < 0).any(axis=2)
    count = int(negative.sum())
    if 0 < count <= NEGATIVE_SHARE * negative.size:  # a resampling filter's ringing (Lanczos, bicubic) round bright spots
        np.maximum(px, 0.0, out=px, where=np.isfinite(px))
        warnings.warn(f"{path}: {count} pixel(s) had negative values (a resampling filter's ringing): set to 0", stacklevel=2)
    return EnvMap(px, str(path))


def save_envmap(path, env: EnvMap) -> Path:
    """Write ``env`` as ``.hdr`` (Radiance RGBE, about 1 % precision) or ``.exr`` (float32)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise InputError(path, f"unsupported environment map format {path.suffix!r} (use .hdr or .exr)")
    path.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".exr":
        return write_exr(path, env.pixels)
    import cv2

    done, data = cv2.imencode(".hdr", np.ascontiguousarray(env.pixels[..., ::-1]))
    if not done:
        raise InputError(path, "cannot encode the Radiance HDR image")
    with atomic_path(path) as tmp:
        tmp.write_bytes(data.tobytes())
    return path
