"""The camera model shared by the scene bundle, the GL engine and the torch twin.

Camera space is OpenGL's: x right, y up, z towards the viewer; the camera sits at the origin and
looks along -z. Image row 0 is the top row; pixel (row i, column j) has its centre at
(u, v) = (j + 0.5, i + 0.5). A perspective camera with a ``focal_mm`` lens on a ``sensor_mm``
sensor spanning the larger image side (the paper: 50 mm on 36 mm, camera 4 m from the subject).
Depth is the distance along -z in metres, so the point seen at pixel (u, v) with depth d is
``((u - cx) d / f, -(v - cy) d / f, -d)``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

FULL_FRAME_MM = 36.0  # the longer side of a 35-mm frame: what a 35-mm-equivalent focal length is relative to


def focal_pixels(focal_mm: float, size: tuple[int, int], sensor_mm: float = FULL_FRAME_MM) -> float:
    """The focal length in pixels of a ``focal_mm`` lens on a frame of ``size`` (w, h) whose longer
    side spans ``sensor_mm`` (default: a 35-mm-equivalent focal length). Every focal length in
    pixels is this one."""
    return focal_mm / sensor_mm * max(size)


def pixel_rays(size: tuple[int, int], focal_px: float) -> np.ndarray:
    """(H, W, 3) float64 unit camera-space directions through the pixel centres of a frame of
    ``size`` (w, h) seen through ``focal_px`` (the principal point at its centre, towards -z)."""
    w, h = size
    u = (np.arange(w, dtype=np.float64) + 0.5 - w / 2.0) / focal_px
    v = -(np.arange(h, dtype=np.float64) + 0.5 - h / 2.0) / focal_px
    uu, vv = np.meshgrid(u, v)
    d = np.stack([uu, vv, -np.ones_like(uu)], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


@dataclass(frozen=True)
class Camera:
    width: int
    height: int
    focal_mm: float = 50.0
    sensor_mm: float = FULL_FRAME_MM
    distance: float = 4.0  # metres from the camera to the subject's centre (depth-network median)

    @property
    def focal_px(self) -> float:
        return self.focal_at((self.width, self.height))

    def focal_at(self, size: tuple[int, int]) -> float:
        """The focal length in pixels of a frame of ``size`` (w, h) this lens spans (its longer side)."""
        return focal_pixels(self.focal_mm, size, self.sensor_mm)

    @property
    def center(self) -> tuple[float, float]:
        return self.width / 2.0, self.height / 2.0

    def to_json(self) -> dict:
        d = asdict(self)
        d["model"] = "perspective"
        return d

    @staticmethod
    def from_json(d: dict) -> Camera:
        """Raises ValueError for anything but a perspective camera with positive finite values."""
        if d.get("model", "perspective") != "perspective":
            raise ValueError(f"camera model must be 'perspective', got {d.get('model')!r}")
        for name in ("width", "height"):
            if isinstance(d[name], bool) or not isinstance(d[name], (int, float)) or not 1 <= d[name] <= 65536:
                raise ValueError(f"{name} must be a whole number of pixels in [1, 65536], got {d[name]!r}")
        cam = Camera(
            width=int(d["width"]),
            height=int(d["height"]),
            focal_mm=float(d.get("focal_mm", 50.0)),
            sensor_mm=float(d.get("sensor_mm", FULL_FRAME_MM)),
            distance=float(d.get("distance", 4.0)),
        )
        for name, (low, high) in (("focal_mm", (0.1, 1e5)), ("sensor_mm", (0.1, 1e4)), ("distance", (1e-3, 1e5))):
            value = getattr(cam, name)
            if not (np.isfinite(value) and low <= value <= high):
                raise ValueError(f"{name} must be a number in [{low:g}, {high:g}], got {value}")
        if cam.width < 1 or cam.height < 1:
            raise ValueError(f"resolution must be positive, got {cam.width}x{cam.height}")
        return cam

    def unproject(self, depth: np.ndarray) -> np.ndarray:
        """Camera-space points (H, W, 3) float32 from a depth map (H, W) in metres."""
        h, w = depth.shape
        f = self.focal_px
        cx, cy = self.center
        u = np.arange(w, dtype=np.float64) + 0.5
        v = np.arange(h, dtype=np.float64) + 0.5
        uu, vv = np.meshgrid(u, v)
        d = depth.astype(np.float64)
        pts = np.stack([(uu - cx) * d / f, -(vv - cy) * d / f, -d], axis=-1)
        return pts.astype(np.float32)

    def view_directions(self) -> np.ndarray:
        """(H, W, 3) float64 unit camera-space direction through every pixel centre (the rays of
        :meth:`unproject`, towards -z)."""
        return pixel_rays((self.width, self.height), self.focal_px)

    def projection_matrix(self, near: float, far: float) -> np.ndarray:
        """OpenGL clip-from-camera matrix (4x4, row-major numpy) matching :meth:`unproject`."""
        f = self.focal_px
        w, h = self.width, self.height
        m = np.zeros((4, 4), dtype=np.float64)
        m[0, 0] = 2.0 * f / w
        m[1, 1] = 2.0 * f / h
        m[2, 2] = -(far + near) / (far - near)
        m[2, 3] = -2.0 * far * near / (far - near)
        m[3, 2] = -1.0
        return m
