"""Image error metrics of the benchmarks: RMSE over a mask, SSIM over the mask's bounding box and
NVIDIA's FLIP on the images tone mapped to sRGB (images scaled to the [0, 1] range by the caller)."""

from __future__ import annotations

import numpy as np

from ..imageio import linear_to_srgb


def srgb(x):
    return linear_to_srgb(np.clip(x, 0.0, 1.0))


def _box(mask):
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    return slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)


def metrics(pred: np.ndarray, truth: np.ndarray, mask: np.ndarray, data_range: float = 1.0, flip: bool = False) -> dict:
    """RMSE over the mask, SSIM over the mask's bounding box (zero outside the mask), and FLIP."""
    from skimage.metrics import structural_similarity

    p = np.where(mask[..., None], np.atleast_3d(pred), 0.0).astype(np.float64)
    t = np.where(mask[..., None], np.atleast_3d(truth), 0.0).astype(np.float64)
    out = {"rmse": float(np.sqrt(((p - t) ** 2)[mask].mean()))}
    rs, cs = _box(mask)
    pb, tb = p[rs, cs], t[rs, cs]
    if data_range == 1.0:
        pb, tb = np.clip(pb, 0, 1), np.clip(tb, 0, 1)
    out["ssim"] = float(structural_similarity(tb, pb, data_range=data_range, channel_axis=-1, win_size=7))
    if flip:
        import flip_evaluator

        ref, test = srgb(tb).astype(np.float32), srgb(pb).astype(np.float32)
        if ref.shape[-1] == 1:
            ref, test = np.repeat(ref, 3, -1), np.repeat(test, 3, -1)
        out["flip"] = float(flip_evaluator.evaluate(ref, test, "LDR", applyMagma=False)[1])
    return out
