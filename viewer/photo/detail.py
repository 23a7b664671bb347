"""Detail from the photo: the detail albedo the frame composite multiplies by the new shading.

The networks see the person at 256 pixels, so their albedo carries none of the photo's fine
texture (faces, hair, cloth weave). The frame composite draws ``A_frame D_new + S_new`` at the
photo's own resolution, with the new shading sums D, S brought from the work resolution; the
photo's detail comes in through ``A_frame``, made once at inference by one of:

- ``network``: the network's albedo, upsampled (no detail: what the product did before);
- ``highpass``: the network's albedo times the photo's high-frequency ratio, photo over its
  low-pass (a mask-normalized Gaussian of about one network pixel);
- ``quotient``: the photo divided by its own shading: ``Q = (photo - S_old) / D_old`` with D_old,
  S_old the shading sums under the photo's estimated lights (:mod:`viewer.photo.own_lighting`:
  colourless, so Q keeps the photo's colours), upsampled exactly as the frame composite upsamples
  the new ones. Under new lights the output is then the photo times D_new / D_old, the quotient
  image, with the old highlights taken out.
  Where D_old is dark (below ``DARK`` of its mean over the person) the quotient is noise over a
  small number: there it fades to ``highpass``. The subtraction of the old highlights keeps at
  least ``HIGHLIGHT_KEEP`` of every channel of a pixel, and its hue (:func:`sheen_room`).
  Q carries whatever of the photo's light the model did not explain. Where Q is *darker* than the
  network's albedo N at coarse scale, that is mostly albedo the network missed (black clothes,
  dark hair: kept as the photo has them); where it is *brighter*, it is mostly light the model
  missed (highlights it underestimated, light where it put a shadow), which must not become
  albedo and stay when the light moves. So, with LP a Gaussian of ``SHARED_SCALE`` network pixels
  and Y the luminance, ``A = Q min(1, Y(LP(N)) / Y(LP(Q)))^BRIGHT_SHARE``: of a coarse excess of
  brightness over the network's albedo, the share ``BRIGHT_SHARE`` (in log) is left to the light;
  detail finer than that scale, and colour, stay the photo's. Measured on held-out pairs against
  the ray-traced truth, this makes the relit RMSE, SSIM and FLIP better than the network's albedo
  alone, where the plain quotient is worse on RMSE (docs/photos.md). Relit under the photo's own
  lights the output is the photo up to that correction.

The method is chosen by measurement (docs/photos.md; ``relight bench photos``): ``DEFAULT``.
"""

from __future__ import annotations

import numpy as np

from viewer.resize import resize

METHODS = ("quotient", "highpass", "network")
DEFAULT = "quotient"
DARK = 0.1  # D_old below this fraction of its mean over the person: the quotient fades out
HIGHLIGHT_KEEP = 0.5  # removing the old specular keeps at least this fraction of the photo
MAX_RATIO = 4.0  # bound of the high-frequency ratio (a speck of glare over a dark low-pass)
LOWPASS_SHRINK = 2.0  # a low-pass of sigma s runs on the image shrunk by s / this (at least 2 pixels of sigma remain)
SHARED_SCALE = 0.25  # network pixels: the scale at which the quotient is compared with the network's albedo
BRIGHT_SHARE = 0.5  # of a coarse excess of brightness over the network's albedo, the share (log) left to the light
CLEAN_DARK = 0.35  # of the person's median D_old: shading darker than this has its albedo regularized (clean_in_shade)
CLEAN_CONTRAST = 0.15  # ln-luminance: a step of the photo larger than this is kept through the regularization
CLEAN_RADIUS = 2  # pixels: the regularization's reach


def luminance(rgb: np.ndarray) -> np.ndarray:
    return rgb @ np.array([0.2126, 0.7152, 0.0722], np.float32)


def masked_lowpass(image: np.ndarray, weight: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian low-pass of ``image`` (H, W[, C]) over the pixels ``weight`` (H, W) covers, each
    pixel the weighted mean of its neighbourhood (OpenCV's Gaussian, normalized convolution). A
    wide Gaussian runs on the image shrunk by up to half its sigma (area average) and is brought
    back bilinearly: the same low-pass at a fraction of the cost."""
    import cv2

    if sigma <= 0:
        return image.astype(np.float32)
    h, w = weight.shape
    w32 = weight.astype(np.float32)
    num = image.astype(np.float32) * (w32[..., None] if image.ndim == 3 else w32)
    factor = max(1, int(sigma / LOWPASS_SHRINK))
    if factor > 1:
        size = (max(w // factor, 1), max(h // factor, 1))
        num = resize(num, size, "area")
        w32 = resize(w32, size, "area")
        sigma = sigma * size[0] / w
    k = 2 * int(np.ceil(3 * sigma)) + 1
    num = cv2.GaussianBlur(num, (k, k), sigma, borderType=cv2.BORDER_REFLECT)
    den = np.maximum(cv2.GaussianBlur(w32, (k, k), sigma, borderType=cv2.BORDER_REFLECT), 1e-6)
    out = num / (den[..., None] if num.ndim == 3 else den)
    if factor > 1:
        out = resize(out, (w, h), "linear")
    return out.reshape(image.shape).astype(np.float32, copy=False)


def sheen_room(colour: np.ndarray, specular: np.ndarray) -> np.ndarray:
    """(H, W) in [0, 1]: the share of the sheen ``specular`` (H, W, 3) that the photo's ``colour``
    (H, W, 3, linear) leaves room for. A sheen adds its colour to every channel of a pixel, so the
    photo's darkest channel bounds it: at most ``1 - HIGHLIGHT_KEEP`` of each channel may be sheen.
    One share per pixel, for all channels alike, so that taking the sheen out keeps its hue (a
    per-channel bound took less from a saturated colour's dark channels than from its bright one)."""
    room = (1.0 - HIGHLIGHT_KEEP) * np.asarray(colour, np.float32) / np.maximum(np.asarray(specular, np.float32), 1e-12)
    # the channels' minimum as two element-wise minima: numpy's reduce over a last axis of 3 took 29 ms at 720p, these 4
    return np.clip(np.minimum(np.minimum(room[..., 0], room[..., 1]), room[..., 2]), 0.0, 1.0).astype(np.float32)


def highpass_ratio(photo: np.ndarray, alpha: np.ndarray, sigma: float) -> np.ndarray:
    """photo / low-pass(photo) per channel inside the matte (1 outside), bounded by MAX_RATIO."""
    low = masked_lowpass(photo, alpha > 0.5, sigma)
    floor = 1e-3 * max(float(photo[alpha > 0.5].mean()) if (alpha > 0.5).any() else 1.0, 1e-6)
    ratio = (photo + floor) / (low + floor)
    return np.where(alpha[..., None] > 0, np.clip(ratio, 0.0, MAX_RATIO), 1.0).astype(np.float32)


def clean_in_shade(albedo: np.ndarray, photo: np.ndarray, diffuse: np.ndarray, person: np.ndarray) -> tuple[np.ndarray, float]:
    """(``albedo`` regularized where the photo's own light was dim, the share of the person touched).

    Where the photo's shading D_old is dark, the photo's grain is a large part of each pixel, and
    the quotient keeps it as albedo: lit anew, a shaded leg or cheek comes out speckled. There the
    albedo is replaced, by a weight from 0 at ``CLEAN_DARK`` of the person's median shading to 1 at
    none, by its joint bilateral filter (OpenCV's ximgproc) guided by the photo's log-luminance: a
    step the photo shows (an edge of cloth, a freckle of contrast beyond ``CLEAN_CONTRAST``) is kept,
    grain under it is averaged over ``CLEAN_RADIUS`` pixels."""
    import cv2

    y = luminance(diffuse)
    median = float(np.median(y[person])) if person.any() else 0.0
    if median <= 0:
        return albedo, 0.0
    weight = np.clip(1.0 - y / (CLEAN_DARK * median), 0.0, 1.0) * person
    if not (weight > 0).any():
        return albedo, 0.0
    guide = np.log(np.maximum(luminance(photo), 1e-4)).astype(np.float32)
    smooth = cv2.ximgproc.jointBilateralFilter(guide, albedo.astype(np.float32), 2 * CLEAN_RADIUS + 1, CLEAN_CONTRAST,
                                               CLEAN_RADIUS)
    out = albedo + weight[..., None] * (smooth - albedo)
    return out.astype(np.float32), float((weight[person] > 0).mean())


def detail_albedo(method: str, photo: np.ndarray, alpha: np.ndarray, network_albedo: np.ndarray,
                  shading: tuple[np.ndarray, np.ndarray] | None, lowpass_sigma: float,
                  shared_scale: float | None = None) -> tuple[np.ndarray, dict]:
    """(A_frame (H, W, 3) in [0, 1], statistics) at the frame's resolution.

    ``photo`` linear (H, W, 3); ``alpha`` the matte; ``network_albedo`` the network's albedo
    brought to the frame; ``shading`` = (D_old, S_old) at the frame (needed by ``quotient``);
    ``lowpass_sigma`` one network pixel in frame pixels (the high-pass's scale); ``shared_scale``
    the scale (network pixels) of the quotient's comparison with the network's albedo (0: none,
    the plain quotient)."""
    if method not in METHODS:
        raise ValueError(f"detail method must be one of {', '.join(METHODS)}, got {method!r}")
    inside = alpha > 0
    stats = {"method": method}
    if method == "network":
        albedo = network_albedo
    else:
        albedo = network_albedo * highpass_ratio(photo, alpha, lowpass_sigma)
        if method == "quotient":
            if shading is None:
                raise ValueError("the quotient needs the photo's own shading")
            diffuse, specular = shading
            person = alpha > 0.5
            mean = diffuse[person].mean(axis=0) if person.any() else np.ones(3, np.float32)
            floor = np.maximum(DARK * mean, 1e-12).astype(np.float32)
            removed = specular * sheen_room(photo, specular)[..., None]
            lit = photo - removed
            quotient = lit / np.maximum(diffuse, floor)
            # weight 0 below the floor, 1 from twice the floor up, per channel
            w = np.clip(diffuse / floor - 1.0, 0.0, 1.0)
            albedo = w * quotient + (1.0 - w) * albedo
            shared_scale = SHARED_SCALE if shared_scale is None else shared_scale
            if shared_scale > 0:
                sigma = shared_scale * lowpass_sigma
                low_q = luminance(masked_lowpass(albedo, person, sigma))
                low_n = luminance(masked_lowpass(network_albedo, person, sigma))
                excess = np.maximum(low_q, 1e-4) / np.maximum(low_n, 1e-4)
                albedo = albedo / np.maximum(excess, 1.0)[..., None] ** BRIGHT_SHARE
            albedo, stats["cleaned_fraction"] = clean_in_shade(albedo, photo, diffuse, person)
            stats["dark_fraction"] = float((w[person] < 1).any(axis=-1).mean()) if person.any() else 0.0
            stats["highlight_removed"] = float(removed[person].mean() / max(float(photo[person].mean()), 1e-12)) \
                if person.any() else 0.0
    clipped = (albedo > 1.0).any(axis=-1) & inside
    stats["clipped_fraction"] = float(clipped.sum() / max(int(inside.sum()), 1))
    albedo = np.maximum(albedo, 0.0)
    albedo = albedo / np.maximum(albedo.max(axis=-1, keepdims=True), 1.0)  # brought into [0, 1] whole: its hue kept
    return np.where(inside[..., None], albedo, 0.0).astype(np.float32), stats
