"""Image error metrics of the benchmarks: RMSE over a mask, SSIM over the mask's bounding box and
NVIDIA's FLIP on the images tone mapped to sRGB (images scaled to the [0, 1] range by the caller)."""

from __future__ import annotations

import numpy as np

from viewer.imageio import linear_to_srgb


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


def chroma(pred: np.ndarray, truth: np.ndarray, mask: np.ndarray, eps: float = 1e-3) -> dict:
    """How far an albedo's colours are from the truth's, brightness aside: the mean L1 between
    chromaticities rgb / (r + g + b) over the mask (where the truth is not black), and the mean
    saturation (L1 distance of the chromaticity from grey, 1/3 each) of both: a prediction that
    washes colours out has a lower saturation than the truth."""
    p, t = np.asarray(pred, np.float64)[mask], np.asarray(truth, np.float64)[mask]
    keep = t.sum(-1) > eps
    cp = p[keep] / np.maximum(p[keep].sum(-1, keepdims=True), eps)
    ct = t[keep] / np.maximum(t[keep].sum(-1, keepdims=True), eps)
    if not len(ct):
        return {"chroma_l1": 0.0, "saturation_pred": 0.0, "saturation_true": 0.0}
    return {"chroma_l1": float(np.abs(cp - ct).sum(-1).mean()), "saturation_pred": float(np.abs(cp - 1 / 3).sum(-1).mean()),
            "saturation_true": float(np.abs(ct - 1 / 3).sum(-1).mean())}


def _luminance(rgb: np.ndarray) -> np.ndarray:
    return np.asarray(rgb, np.float64)[..., :3] @ np.array([0.2126, 0.7152, 0.0722])


def eroded(mask: np.ndarray, fraction: float = 0.005) -> np.ndarray:
    """The mask eroded by ``fraction`` of the image's longer side (at least 3 pixels): the
    person without their silhouette edge."""
    import cv2

    r = max(3, int(round(fraction * max(mask.shape))))
    return cv2.erode(mask.astype(np.uint8), np.ones((2 * r + 1, 2 * r + 1), np.uint8)) > 0


def detail_level(image: np.ndarray, mask: np.ndarray) -> float:
    """Mean |Laplacian| of the luminance over ``mask`` divided by the mean luminance there."""
    import cv2

    lum = _luminance(image)
    lap = np.abs(cv2.Laplacian(lum, cv2.CV_64F, ksize=1))
    return float(lap[mask].mean() / max(lum[mask].mean(), 1e-12))


def detail_kept(relit: np.ndarray, photo: np.ndarray, mask: np.ndarray) -> float:
    """*Detail kept*: the relit image's detail level over the photo's, inside the eroded person
    mask, same frame (display images, sRGB in [0, 1]). 1 keeps the photo's detail; below, blur;
    above, over-sharpening."""
    m = eroded(mask)
    return detail_level(relit, m) / max(detail_level(photo, m), 1e-12)


def light_moved(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    """How much two renders of the person under different lights differ: mean |Y_a - Y_b| over
    the mean of (Y_a + Y_b) / 2, inside the eroded mask (linear HDR; 0 = the light changed
    nothing, 2 = each side lit only in one of them)."""
    m = eroded(mask)
    ya, yb = _luminance(a)[m], _luminance(b)[m]
    return float(np.abs(ya - yb).mean() / max(0.5 * (ya + yb).mean(), 1e-12))
