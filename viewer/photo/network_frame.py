"""The square of the photo's frame the networks see (:class:`Framing`: the person's height fills
``FILL`` of it), their maps brought back from it to the work frame, and what lies outside their view
filled from its nearest part."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewer.photo.frames import person_box, square

NETWORK_RES = 256
FILL = 0.86  # of the square the person's height spans (the middle of the dataset's range)


@dataclass(frozen=True)
class Framing:
    """The square of the frame the networks see: top-left corner (may be negative) and side, pixels."""

    top: int
    left: int
    side: int

    def to_json(self) -> dict:
        return {"top": self.top, "left": self.left, "side": self.side}


def framing(mask: np.ndarray) -> Framing:
    top, left, height, width = person_box(mask)
    side = int(np.ceil(max(height / FILL, width / 0.95)))
    cy, cx = top + height / 2.0, left + width / 2.0
    return Framing(int(round(cy - side / 2.0)), int(round(cx - side / 2.0)), side)


def crop(image: np.ndarray, f: Framing, mode: str) -> np.ndarray:
    """The framing's square of ``image``; outside the photo: its edge repeated (``edge``) or zero."""
    return square(image, f.top, f.left, f.side, mode)


def extend(values, mask):
    """Fill the pixels outside the mask, ring by ring, with the mean of their filled neighbours:
    the whole square, so that what the person holds beyond the networks' view (the framing is the
    body's, ``Matte.body``) has maps, those of the nearest part the networks saw. ``values`` (B, C,
    H, W) and ``mask`` (B, 1, H, W) torch tensors; each image of the batch by :func:`fill_rings`."""
    import torch

    out = [torch.from_numpy(fill_rings(v.permute(1, 2, 0).cpu().numpy().astype(np.float32), k[0].cpu().numpy() > 0.5))
           for v, k in zip(values, mask)]
    return torch.stack(out).permute(0, 3, 1, 2).to(values.dtype).to(values.device)


def fill_rings(values: np.ndarray, known: np.ndarray) -> np.ndarray:
    """(H, W, C): ``values`` where ``known`` (H, W) bool, and each other pixel the mean of its
    8-neighbours filled before it, ring by ring outwards (ring r: chessboard distance r from the
    known pixels, OpenCV's ``distanceTransform``). Each ring's pixels only are touched, so the cost
    is the unknown pixels', not the rings' count times the image's (a 3x3 mean over the whole image per
    ring took 0.25 s a frame). Nothing known: zeros."""
    import cv2

    h, w, c = values.shape
    if known.all() or not known.any():
        return np.where(known[..., None], values, 0.0).astype(np.float32)
    ring = cv2.distanceTransform((~known).astype(np.uint8), cv2.DIST_C, 3).astype(np.int32)
    filled = np.zeros((h + 2, w + 2, c), np.float32)  # padded by one: a neighbour off the image is never filled
    filled[1:-1, 1:-1] = np.where(known[..., None], values, 0.0)
    rings = np.full((h + 2, w + 2), np.iinfo(np.int32).max, np.int32)
    rings[1:-1, 1:-1] = ring
    order = np.argsort(ring, axis=None, kind="stable")
    last = int(ring.max())
    starts = np.searchsorted(ring.ravel()[order], np.arange(1, last + 2))
    for r in range(1, last + 1):
        ys, xs = np.divmod(order[starts[r - 1]:starts[r]], w)
        total = np.zeros((len(ys), c), np.float32)
        count = np.zeros(len(ys), np.float32)
        for dy in (0, 1, 2):
            for dx in (0, 1, 2):
                near = rings[ys + dy, xs + dx] < r
                total += filled[ys + dy, xs + dx] * near[:, None]
                count += near
        filled[ys + 1, xs + 1] = total / count[:, None]
    return filled[1:-1, 1:-1]


def to_work_frame(stack, f: Framing, work_size: tuple[int, int], work_scale: float):
    """The networks' maps (1, C, R, R) over the framing's square, resampled (bilinear) at the
    centres of the work frame's pixels: (H, W, C) numpy. A work pixel (x, y) is the frame point
    ((x + 0.5) / s, (y + 0.5) / s); outside the square the border is repeated (never in the mask)."""
    import torch
    from torch.nn import functional as F

    w, h = work_size
    xs = ((torch.arange(w, dtype=torch.float64) + 0.5) / work_scale - f.left) / f.side * 2.0 - 1.0
    ys = ((torch.arange(h, dtype=torch.float64) + 0.5) / work_scale - f.top) / f.side * 2.0 - 1.0
    gy, gx = torch.meshgrid(ys, xs, indexing="ij")
    grid = torch.stack([gx, gy], dim=-1)[None].to(stack.dtype)
    out = F.grid_sample(stack, grid, mode="bilinear", padding_mode="border", align_corners=False)
    return out[0].permute(1, 2, 0).cpu().numpy()


def map_stack(maps: dict, depth):
    """(B, 9, H, W): the networks' maps (:func:`viewer.nets.inverse.maps`) and metric depth, in
    the channel order :func:`scene_maps` reads."""
    import torch

    return torch.cat([maps["albedo"], maps["specular"], maps["roughness"], maps["normal"], depth], dim=1)


def scene_maps(work: np.ndarray, mask: np.ndarray, distance: float) -> dict:
    """A scene's albedo, specular, roughness, normal and depth from a resampled :func:`map_stack`
    (H, W, 9): clipped to their ranges, normals made unit, zero outside ``mask`` (depth: the
    camera's ``distance``, and at least 0.1 m inside)."""
    normal = work[..., 5:8] / np.maximum(np.linalg.norm(work[..., 5:8], axis=-1, keepdims=True), 1e-6)
    inside = mask[..., None]
    return {"albedo": np.where(inside, np.clip(work[..., :3], 0, 1), 0).astype(np.float32),
            "specular": np.where(mask, np.clip(work[..., 3], 0, 1), 0).astype(np.float32),
            "roughness": np.where(mask, np.clip(work[..., 4], 0, 1), 0).astype(np.float32),
            "normal": np.where(inside, normal, 0).astype(np.float32),
            "depth": np.where(mask, np.maximum(work[..., 8], 0.1), distance).astype(np.float32)}
