"""Operations on scene bundles: resampling that keeps them valid, and checking normals against
the depth geometry (used by benchmarks, the synthetic data and tests)."""

from __future__ import annotations

import numpy as np

from viewer.errors import InputError
from viewer.scene.bundle import Scene, load_scene
from viewer.scene.camera import Camera


def load_sized_scene(path, size: int | None = None, max_size: int | None = None) -> Scene:
    """The scene bundle at ``path``, its maps resampled to ``size`` pixels on the longer side when
    given (``--size``), its frame capped to ``max_size`` (``--max-size``)."""
    from viewer.resize import scaled_size

    scene = load_scene(path)
    if size is not None and not 16 <= size <= 8192:
        raise InputError(None, f"--size must be within [16, 8192] pixels, got {size}")
    if max_size is not None and not 16 <= max_size <= 16384:
        raise InputError(None, f"--max-size must be within [16, 16384] pixels, got {max_size}")
    _check_render_memory(scene, size, max_size)
    if size is not None:
        scene = resample_scene(scene, size, keep_frame=True)
    if max_size is not None:
        if scene.frame is not None and max(scene.output_size) > max_size:
            scene.frame = scene.frame.resized(scaled_size(scene.output_size, max_size))
        elif scene.frame is None and max(scene.output_size) > max_size:
            scene = resample_scene(scene, max_size)
    return scene


def _check_render_memory(scene: Scene, size: int | None, max_size: int | None) -> None:
    """Refuse, before resampling, maps and a frame whose render would not fit this machine's memory
    (``render --size 8192`` was killed by the kernel at 23.6 GB): see :mod:`viewer.memory_needs`."""
    from viewer import memory_needs
    from viewer.resize import scaled_size

    h, w = scene.height, scene.width
    long_side = size if size is not None else max(h, w)
    aspect = min(h, w) / max(h, w)
    if scene.frame is not None:
        frame = scene.output_size if max_size is None or max(scene.output_size) <= max_size \
            else scaled_size(scene.output_size, max_size)
    else:  # the maps are the frame, at most max_size
        long_side = min(long_side, max_size) if max_size is not None else long_side
        frame = (long_side, long_side * aspect)
    map_pixels = long_side * long_side * aspect
    frame_pixels = int(frame[0] * frame[1])
    memory_needs.require(memory_needs.render_bytes(map_pixels, frame_pixels), f"rendering maps of {long_side} px",
                   f"--size {memory_needs.largest_render_size(aspect, frame_pixels)} or less fits")


def resample_scene(scene: Scene, size: int, keep_frame: bool = False) -> Scene:
    """Nearest-neighbour resample of the maps to ``size`` pixels on the longer side (maps stay
    valid: unit normals, binary mask); the camera keeps its lens, so the figure covers the same
    field of view. The frame layer (output resolution) is kept with ``keep_frame``, else dropped:
    the scene then renders at the maps' size (the viewer's drag preview)."""
    h, w = scene.height, scene.width
    scale = size / max(h, w)
    nh, nw = max(int(round(h * scale)), 1), max(int(round(w * scale)), 1)
    rows = np.minimum(((np.arange(nh) + 0.5) / scale).astype(int), h - 1)
    cols = np.minimum(((np.arange(nw) + 0.5) / scale).astype(int), w - 1)

    def pick(a):
        return None if a is None else np.ascontiguousarray(a[rows][:, cols])

    cam = scene.camera
    return Scene(
        albedo=pick(scene.albedo), specular=pick(scene.specular), roughness=pick(scene.roughness),
        normal=pick(scene.normal), depth=pick(scene.depth), mask=pick(scene.mask),
        camera=Camera(nw, nh, cam.focal_mm, cam.sensor_mm, cam.distance),
        photo=pick(scene.photo), background=pick(scene.background),
        frame=scene.frame if keep_frame else None,
    ).validate()


def normals_from_depth(cam: Camera, depth: np.ndarray, mask: np.ndarray, max_jump: float = 0.02):
    """Central-difference normals of the unprojected depth map; valid where the 4-neighbourhood is
    inside the mask and has no depth jump above ``max_jump`` metres."""
    p = cam.unproject(np.where(mask, depth, 1.0)).astype(np.float64)
    du = np.zeros_like(p)
    dv = np.zeros_like(p)
    du[:, 1:-1] = p[:, 2:] - p[:, :-2]
    dv[1:-1] = p[2:] - p[:-2]
    n = np.cross(dv, du)  # dv points down (-y), du right (+x): dv x du = +z for a fronto-parallel plane
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    valid = mask.copy()
    valid[0] = valid[-1] = False
    valid[:, 0] = valid[:, -1] = False
    for axis in (0, 1):
        for sh in (1, -1):
            nb_m = np.roll(mask, sh, axis=axis)
            nb_d = np.roll(depth, sh, axis=axis)
            valid &= nb_m & (np.abs(nb_d - depth) < max_jump)
    return n, valid


def depth_normal_angle(scene: Scene):
    n_d, valid = normals_from_depth(scene.camera, scene.depth, scene.mask)
    cos = np.clip((n_d * scene.normal).sum(-1), -1.0, 1.0)
    ang = np.degrees(np.arccos(cos))
    return ang, valid
