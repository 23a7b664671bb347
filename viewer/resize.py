"""Images resized and sizes scaled, the one way every stage does it: an area average when shrinking,
bilinear when enlarging (OpenCV), sizes scaled to a longer side. At the bottom of the package: the
scene bundle resamples its maps with it, the photo stages their frames."""

from __future__ import annotations

import numpy as np


def scaled_size(size: tuple[int, int], longest: int) -> tuple[int, int]:
    """``size`` (w, h) scaled so the longer side is ``longest`` (never below 1 pixel)."""
    w, h = size
    s = longest / max(w, h)
    return max(int(round(w * s)), 1), max(int(round(h * s)), 1)


def height_capped(size: tuple[int, int], height: float, at_most: int) -> tuple[int, int]:
    """``size`` (w, h) as it is, or scaled down so that something ``height`` pixels tall in it is
    ``at_most`` pixels tall (where a person is solved at a bounded size)."""
    w, h = size
    return (w, h) if height <= at_most else scaled_size((w, h), int(round(max(w, h) * at_most / height)))


def resize(image: np.ndarray, size: tuple[int, int], method: str = "auto") -> np.ndarray:
    """``image`` (H, W[, C]) resized to ``size`` = (w, h) (OpenCV; float32 or uint8 kept, any number
    of channels). ``method``: ``"auto"`` (an area average when shrinking, bilinear when enlarging),
    or one of them always (``"area"``, ``"linear"``, ``"cubic"``: sharper when enlarging), or
    ``"nearest"`` (labels and masks kept two-valued). At the same size ``image`` itself comes back (not a copy)."""
    import cv2

    h, w = image.shape[:2]
    if (w, h) == tuple(size):
        return image
    if method == "auto":
        method = "area" if size[0] <= w and size[1] <= h else "linear"
    channels = image.shape[2] if image.ndim == 3 else 0
    if channels > 4:  # OpenCV resizes up to 4 channels at a time
        return np.concatenate([resize(image[..., i:i + 4], size, method) for i in range(0, channels, 4)], axis=-1)
    flag = {"area": cv2.INTER_AREA, "linear": cv2.INTER_LINEAR, "cubic": cv2.INTER_CUBIC, "nearest": cv2.INTER_NEAREST}[method]
    out = cv2.resize(image, tuple(int(v) for v in size), interpolation=flag)
    return out[..., None] if channels == 1 else out


def mask_normalized_resize(image: np.ndarray, weight: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """:func:`resize` of ``image`` (H, W, C) weighted by ``weight`` (H, W): what lies outside a
    person does not darken its edge."""
    num = resize((image * weight[..., None]).astype(np.float32), size)
    den = resize(weight.astype(np.float32), size)
    return num / np.maximum(den, 1e-6)[..., None]
