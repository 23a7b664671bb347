"""Image error metrics of the benchmarks: RMSE over a mask, SSIM over the mask's bounding box and
NVIDIA's FLIP on the images tone mapped to sRGB (images scaled to the [0, 1] range by the caller)."""

from __future__ import annotations

import numpy as np

from viewer.files.imageio import linear_to_srgb


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


def luminance(rgb: np.ndarray) -> np.ndarray:
    """Rec. 709 luminance of linear RGB (float64)."""
    return np.asarray(rgb, np.float64)[..., :3] @ np.array([0.2126, 0.7152, 0.0722])


def cielab(srgb8: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32 CIELAB (L* in [0, 100], a* and b* about 0) of an 8-bit sRGB image, by OpenCV."""
    import cv2

    lab = cv2.cvtColor(srgb8, cv2.COLOR_RGB2LAB).astype(np.float32)
    lab[..., 0] *= 100.0 / 255.0
    lab[..., 1:] -= 128.0
    return lab


def border(image: np.ndarray) -> np.ndarray:
    """(N, C): the pixels of an image's four edges."""
    return np.concatenate([image[0], image[-1], image[:, 0], image[:, -1]])


def eroded(mask: np.ndarray, fraction: float = 0.005) -> np.ndarray:
    """The mask eroded by ``fraction`` of the image's longer side (at least 3 pixels): the
    person without their silhouette edge."""
    import cv2

    r = max(3, int(round(fraction * max(mask.shape))))
    return cv2.erode(mask.astype(np.uint8), np.ones((2 * r + 1, 2 * r + 1), np.uint8)) > 0


def detail_level(image: np.ndarray, mask: np.ndarray) -> float:
    """Mean |Laplacian| of the luminance over ``mask`` divided by the mean luminance there."""
    import cv2

    lum = luminance(image)
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
    ya, yb = luminance(a)[m], luminance(b)[m]
    return float(np.abs(ya - yb).mean() / max(0.5 * (ya + yb).mean(), 1e-12))


# --- the matte: the old background left in the relit person ------------------------------------
MATTE_MARGIN = 4.0  # pixels either side of the hand-made outline where the matte may differ freely
BLEED_BAND = 5.0  # pixels inside the product's alpha = 0.5 outline: the edge band
BLEED_CONTROL = (10.0, 15.0)  # the control band (pixels inside)
BLEED_INTERIOR = (10.0, 30.0)  # the person's local interior colour comes from here
BLEED_BACKGROUND = 15.0  # the photo's local background colour comes from this far outside
BLEED_SIGMA = 15.0  # pixels: the window of the local colours
KEPT_DELTA_E = 12.0  # CIE76: a pixel this close to the backdrop colour is the backdrop
BLEED_DARKEST = 0.02  # of the person's median luminance: darker pixels have no chromaticity to judge


def outline(mask: np.ndarray) -> np.ndarray:
    """The mask's pixels with a 4-neighbour outside it."""
    import cv2

    m = mask.astype(np.uint8)
    return (m > 0) & (cv2.erode(m, np.ones((3, 3), np.uint8), borderType=cv2.BORDER_CONSTANT, borderValue=0) == 0)


def spill_cut(alpha: np.ndarray, hand: np.ndarray, margin: float = MATTE_MARGIN) -> dict:
    """Against a hand-made mask: ``spill``, the alpha outside it farther than ``margin`` pixels
    from its outline, and ``cut``, the alpha missing inside it farther than that, each per pixel
    of its outline (pixels of error along the outline, on average)."""
    from viewer.photo.trimap import distances

    hand = hand > 0.5
    length = max(int(outline(hand).sum()), 1)
    inside, outside = distances(hand)
    return {"spill": float(alpha[~hand & (outside > margin)].sum() / length),
            "cut": float((1.0 - alpha)[hand & (inside > margin)].sum() / length)}


def _rg(rgb: np.ndarray) -> np.ndarray:
    rgb = np.asarray(rgb, np.float32)[..., :3]
    return rgb[..., :2] / np.maximum(rgb.sum(-1, keepdims=True), 1e-6)


def _local_mean(values: np.ndarray, where: np.ndarray, sigma: float) -> np.ndarray:
    import cv2

    k = 2 * int(np.ceil(3 * sigma)) + 1
    w = where.astype(np.float32)
    num = cv2.GaussianBlur(values * w[..., None], (k, k), sigma)
    den = cv2.GaussianBlur(w, (k, k), sigma)
    return num / np.maximum(den, 1e-6)[..., None]


def bleed(person: np.ndarray, alpha: np.ndarray, photo: np.ndarray) -> float:
    """How much the old background colours the relit person's edge: in the band within
    ``BLEED_BAND`` pixels inside the alpha = 0.5 outline, the share of pixels whose
    chromaticity (rg of linear RGB) is nearer the photo's local background (within
    ``BLEED_BACKGROUND`` pixels outside) than the person's local interior (``BLEED_INTERIOR``
    pixels inside, in ``person``'s colours), minus the same share in the control band
    ``BLEED_CONTROL`` (what a person's own colours score); pixels darker than ``BLEED_DARKEST`` of
    the person's median have no chromaticity to judge and are left out. ``person``: the relit
    person's colour (not premultiplied), ``photo`` the photo, both linear at the same size."""
    from viewer.photo.trimap import distances

    inside, outside = distances(alpha >= 0.5)
    cp, cb = _rg(person), _rg(photo)
    background = _local_mean(cb, (outside > 0) & (outside <= BLEED_BACKGROUND), BLEED_SIGMA)
    interior = _local_mean(cp, (inside > BLEED_INTERIOR[0]) & (inside <= BLEED_INTERIOR[1]), BLEED_SIGMA)
    nearer = np.linalg.norm(cp - background, axis=-1) < np.linalg.norm(cp - interior, axis=-1)
    brightness = luminance(person)
    person_pixels = inside > 0
    lit = brightness > BLEED_DARKEST * float(np.median(brightness[person_pixels])) if person_pixels.any() else brightness > 0
    band = (inside > 0) & (inside <= BLEED_BAND) & lit
    control = (inside > BLEED_CONTROL[0]) & (inside <= BLEED_CONTROL[1]) & lit
    if not band.any() or not control.any():
        return 0.0
    return float(nearer[band].mean() - nearer[control].mean())


def backdrop_coloured(photo_srgb: np.ndarray) -> np.ndarray:
    """(H, W) bool: the pixels of a photo on a plain backdrop within ``KEPT_DELTA_E`` (CIE76) of the
    backdrop (the median of the photo's border). ``photo_srgb`` (H, W, 3) uint8."""
    lab = cielab(photo_srgb)
    return np.linalg.norm(lab - np.median(border(lab), axis=0), axis=-1) < KEPT_DELTA_E


def kept_backdrop(alpha: np.ndarray, photo_srgb: np.ndarray, truth: np.ndarray,
                  where: np.ndarray | None = None) -> float:
    """For a photo on a plain backdrop: the pixels kept as the person (alpha > 0.5) of the
    backdrop's colour (:func:`backdrop_coloured`), per pixel of the true mask's outline; only
    ``where`` (H, W) bool when given (outside the true mask: backdrop kept, the person's own clothes
    of the backdrop's colour aside; :func:`enclosed_backdrop`)."""
    kept = (alpha > 0.5) & backdrop_coloured(photo_srgb)
    if where is not None:
        kept &= where
    return float(kept.sum() / max(int(outline(truth > 0.5).sum()), 1))


def enclosed_backdrop(alpha: np.ndarray, photo_srgb: np.ndarray) -> np.ndarray:
    """(H, W) bool, for a photo on a plain backdrop and no true mask: the kept pixels (alpha > 0.5)
    of the backdrop's colour in regions of that colour the person encloses, that is, not connected
    through pixels of that colour to the background the matte left out (alpha <= 0.5). A white
    shirt on a white studio meets the studio along its outline and is not counted; a gap between an
    arm and the body kept whole is; a gap kept in part, or open to the background, is not (a lower
    bound of the backdrop kept)."""
    import cv2

    near = backdrop_coloured(photo_srgb)
    count, labels = cv2.connectedComponents(near.astype(np.uint8), connectivity=8)
    open_ = np.zeros(count, bool)
    open_[np.unique(labels[near & (alpha <= 0.5)])] = True
    return near & (alpha > 0.5) & ~open_[labels]


def enclosed_gaps(truth: np.ndarray, fraction: float = 0.06) -> np.ndarray:
    """(H, W) bool: the background a true mask's person encloses or nearly, its concavities (the
    mask closed by a disc of ``fraction`` of the person's height, less the mask: between an arm and
    the body, a hand and the head, the legs), farther than ``MATTE_MARGIN`` from its outline."""
    import cv2

    from viewer.photo.pose_masks import person_height
    from viewer.photo.trimap import distances

    person = truth > 0.5
    r = max(1, int(fraction * person_height(person)))
    closed = cv2.morphologyEx(person.astype(np.uint8), cv2.MORPH_CLOSE,
                              cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2)) > 0
    return closed & ~person & (distances(person)[1] > MATTE_MARGIN)


def gaps_found(alpha: np.ndarray, truth: np.ndarray) -> dict:
    """Against a true mask, in its :func:`enclosed_gaps`: ``found``, the share of their pixels with
    alpha under 0.1 (None without gaps), and ``kept``, the alpha left there per pixel of the mask's
    outline."""
    gaps = enclosed_gaps(truth)
    return {"found": float((alpha[gaps] < 0.1).mean()) if gaps.any() else None,
            "kept": float(alpha[gaps].sum() / max(int(outline(truth > 0.5).sum()), 1))}


def on_backdrop(photo_srgb: np.ndarray, matte: np.ndarray, colour=(236, 150, 190)) -> np.ndarray:
    """The person of ``photo_srgb`` (uint8) over a flat ``colour``, by ``matte`` (a hand-made mask):
    a plain-backdrop test photo, the backdrop seen wherever the person's own background was
    (between the arm and the body, between the feet)."""
    a = np.clip(matte.astype(np.float32), 0, 1)[..., None]
    return (a * photo_srgb + (1 - a) * np.array(colour, np.float32) + 0.5).astype(np.uint8)


def on_studio(photo_srgb: np.ndarray, matte: np.ndarray, colour=(236, 150, 190), seed: int = 0) -> np.ndarray:
    """As :func:`on_backdrop`, on a studio's backdrop of ``colour`` instead of a flat one: lighter
    above and darker below (12 %), a floor from the feet down 10 % darker, the person's shadow cast
    on the backdrop beside them (their mask moved by 3.5 % of their height, blurred by 1.2 %, 22 %
    darker), a soft contact shadow under the feet (30 % darker) and the camera's noise (1.5 levels)."""
    import cv2

    person = matte > 0.5
    h, w = person.shape
    rows = np.flatnonzero(person.any(axis=1))
    top, bottom = rows[0], rows[-1]
    tall = bottom - top + 1
    y = np.arange(h, dtype=np.float32)[:, None, None]
    backdrop = np.array(colour, np.float32) * (1.06 - 0.12 * y / h)
    backdrop = backdrop * (1 - 0.1 * np.clip((y - (bottom - 0.03 * tall)) / (0.02 * h), 0, 1))
    cast = np.roll(person.astype(np.float32), (int(-0.01 * tall), int(0.035 * tall)), axis=(0, 1))
    cast = cv2.GaussianBlur(cast, (0, 0), 0.012 * tall)
    feet = np.flatnonzero(person[int(bottom - 0.04 * tall):].any(axis=0))
    contact = np.zeros((h, w), np.float32)
    axes = (int(0.55 * np.ptp(feet)) + 6, int(0.008 * tall) + 2)
    cv2.ellipse(contact, (int(feet.mean()), int(bottom - 0.004 * tall)), axes, 0, 0, 360, 1, -1)
    contact = cv2.GaussianBlur(contact, (0, 0), 0.006 * tall + 1)
    backdrop = backdrop * (1 - 0.22 * cast[..., None]) * (1 - 0.3 * contact[..., None])
    backdrop = backdrop + np.random.default_rng(seed).normal(0, 1.5, backdrop.shape)
    a = np.clip(matte.astype(np.float32), 0, 1)[..., None]
    return np.clip(a * photo_srgb + (1 - a) * backdrop + 0.5, 0, 255).astype(np.uint8)
