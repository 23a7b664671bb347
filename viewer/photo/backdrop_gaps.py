"""The regions of a plain backdrop the person encloses (between the hair and the neck, an arm and the
body, the legs), found at any depth by the backdrop's own colour model: the matte punches them out
(:func:`backdrop_gaps`, :mod:`viewer.photo.matting`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewer.photo.colour_models import inverse_3x3, local_gaussians
from viewer.photo.pose_masks import bones_mask, face_mask, gaps_mask
from viewer.photo.trimap import BONE, Carried, Trimap
from viewer.resize import resize

# Regions of a plain backdrop the person encloses (backdrop_gaps), judged where the band is decided
GAP_WINDOW = 0.06  # of the person's height: the backdrop's colour model is learnt over a Gaussian window this wide
GAP_REG = 2e-5  # added to that model's covariance (colours in [0, 1]): a flat backdrop's floor, under 1/200 per channel
GAP_SUPPORT = 0.02  # the window's weight of sure background under which a pixel has no backdrop model (too deep inside)
PLAIN = 0.08  # a backdrop whose model spreads less than this (the square root of its covariance's trace) is plain
GAP_MATCH = 3.5  # Mahalanobis distance: a pixel this near its backdrop's model has the backdrop's colour
GAP_AREA = 5e-5  # of the height squared: smaller regions are left to the holes and the soft edge (24 px at 700)
GAP_RING = 3  # pixels: the ring around a region whose colours are judged
GAP_CONTRAST = 8.0  # Mahalanobis distance: ring pixels farther than this from the backdrop's model are unlike it
GAP_RING_SHARE = 0.5  # a gap's ring is at least this much unlike the backdrop (an edge nearly all around it)
GAP_PERSON = 0.01  # the person's colours near a region's: the nearest this share of the pose's bones' pixels
GAP_RATIO = 2.5  # the person's colours are at least this many times farther from a gap's colour than its backdrop is
GAP_FLOOR = 1.0  # Mahalanobis distance: the least the backdrop's distance counts for in that ratio
GAP_ON_BONES = 0.5  # a region this much on the pose's bones, torso or face is the person
GAP_SURE = 0.9  # a region where the segmentation is at least this everywhere is the person (it hesitates over a gap)
GAP_CARRIED = 0.5  # a region the frame before had as background over this share of it (a clip's, where the flow holds)


@dataclass(frozen=True)
class BackdropGaps:
    """Regions of a plain backdrop the person encloses (:func:`backdrop_gaps`), at the size the
    band is decided: ``found`` (h, w) bool, and the backdrop's colour model at the pixels around
    them (``index`` (h, w): the pixel's row in ``mean`` (n, 3) and ``inverse`` (n, 3, 3), the
    inverse covariance; -1 where there is none)."""

    found: np.ndarray
    index: np.ndarray
    mean: np.ndarray
    inverse: np.ndarray

    def at(self, photo: np.ndarray, person: np.ndarray) -> np.ndarray:
        """(H, W) bool at ``photo``'s size (float RGB in [0, 1], finer than the regions'): the
        pixels of ``person`` within a pixel of the regions' size of a region whose colour is their
        backdrop's, each judged by the model of its pixel there: the gap's outline to the pixel (a
        hair strand crossing it stays the person's)."""
        import cv2

        h, w = person.shape
        out = np.zeros((h, w), bool)
        if not self.found.any():
            return out
        mh, mw = self.found.shape
        near = cv2.dilate(self.found.astype(np.uint8), np.ones((3, 3), np.uint8))
        ys, xs = np.nonzero(person & (resize(near, (w, h), "nearest") > 0))
        rows = self.index[np.minimum((ys * mh) // h, mh - 1), np.minimum((xs * mw) // w, mw - 1)]
        ys, xs, rows = ys[rows >= 0], xs[rows >= 0], rows[rows >= 0]
        d = photo[ys, xs].astype(np.float32) - self.mean[rows]
        out[ys, xs] = np.einsum("ni,nij,nj->n", d, self.inverse[rows], d) < GAP_MATCH ** 2
        return out


def gap_regions(image: np.ndarray, person: np.ndarray, tri: Trimap, segmentation: np.ndarray, landmarks: dict,
                carried: Carried | None = None):
    """The candidates of :func:`backdrop_gaps`: (their labels (H, W) int, 0 where none; each
    region's figures, a dict per label from 1; the backdrop's model, as :class:`BackdropGaps`
    holds it, with nothing found yet). ``carried``: a clip's frame before (at ``image``'s size,
    ``held`` 0 or 1), whose background over each region is one of its figures."""
    import cv2

    h, w = person.shape
    around = cv2.dilate(person.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    mean, cov, support = local_gaussians(image, tri.sure_background.astype(np.float32), GAP_WINDOW * tri.height, around,
                                         GAP_REG)
    inverse, _ = inverse_3x3(cov)
    index = np.full((h, w), -1, np.int64)
    index[around] = np.arange(int(around.sum()))
    model = BackdropGaps(np.zeros((h, w), bool), index, mean, inverse)
    rows = index[person]
    d = image[person].astype(np.float32) - mean[rows]
    distance = np.full((h, w), np.inf, np.float32)
    distance[person] = np.sqrt(np.maximum(np.einsum("ni,nij,nj->n", d, inverse[rows], d), 0.0))
    plain = (support > GAP_SUPPORT) & (np.sqrt(np.trace(cov, axis1=1, axis2=2)) < PLAIN)
    candidates = person & (distance < GAP_MATCH)
    candidates[person] &= plain[rows]
    count, labels, stats, _ = cv2.connectedComponentsWithStats(candidates.astype(np.uint8), connectivity=8)
    bones = bones_mask(landmarks, (w, h), max(1, int(round(BONE * tri.height)))) & person
    reference = image[bones].astype(np.float32)
    face = face_mask(landmarks, (w, h))
    # where limbs and body meet (GAPS), a bone drawn beside a gap is no sign of the person: the upper
    # arm's bone and the torso's side run along the gap between the arm and the body
    on_body = bones & ~(gaps_mask(landmarks, (w, h)) & ~(face if face is not None else False))
    ring_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * GAP_RING + 1,) * 2)
    figures = [None]
    for label in range(1, count):
        x, y, bw, bh, area = stats[label]
        if area < GAP_AREA * tri.height ** 2:
            figures.append(None)
            continue
        box = (slice(max(y - GAP_RING, 0), y + bh + GAP_RING), slice(max(x - GAP_RING, 0), x + bw + GAP_RING))
        region = labels[box] == label
        ring = (cv2.dilate(region.astype(np.uint8), ring_kernel) > 0) & ~candidates[box] & person[box]
        at = index[box][region]
        colour = np.median(image[box][region], axis=0).astype(np.float32)
        backdrop, inv = mean[at].mean(axis=0), inverse[at].mean(axis=0)
        to_person = np.einsum("ni,ij,nj->n", reference - colour, inv, reference - colour)
        figures.append({
            "area": int(area),
            "ring_unlike": float((distance[box][ring] > GAP_CONTRAST).mean()) if ring.any() else 0.0,
            "to_backdrop": float(np.sqrt(max((colour - backdrop) @ inv @ (colour - backdrop), 0.0))),
            "to_person": float(np.sqrt(max(np.quantile(to_person, GAP_PERSON), 0.0))) if len(reference) else np.inf,
            "on_bones": float(on_body[box][region].mean()),
            "segmentation_least": float(segmentation[box][region].min()),
            "carried_background": float(((carried.held[box] > 0) & (carried.alpha[box] < 0.5))[region].mean())
            if carried is not None else 0.0})
    return labels, figures, model


def is_gap(figures: dict | None) -> bool:
    """Whether a candidate region of :func:`gap_regions` is backdrop seen through the person (the
    guards: :func:`backdrop_gaps`). A region a clip's frame before had as background needs only the
    colour's guards: the edge all around it and the segmentation's hesitation come and go as an arm
    moves along the body, and the same gap was background in one frame and the old wall in the next."""
    if figures is None or figures["to_person"] < GAP_RATIO * max(figures["to_backdrop"], GAP_FLOOR) \
            or figures["on_bones"] >= GAP_ON_BONES:
        return False
    return figures["carried_background"] >= GAP_CARRIED or (
        figures["ring_unlike"] >= GAP_RING_SHARE and figures["segmentation_least"] < GAP_SURE)


def backdrop_gaps(image: np.ndarray, person: np.ndarray, tri: Trimap, segmentation: np.ndarray,
                  landmarks: dict, carried: Carried | None = None) -> BackdropGaps:
    """Regions of a plain backdrop the person encloses (between an arm and the body, a hand and the
    head, a collar and the neck, the legs), found in ``person`` (H, W) bool at ``image``'s size
    (float RGB in [0, 1]); ``segmentation`` the pose model's there, ``landmarks`` its landmarks.

    The backdrop's colour model is a Gaussian of the sure background's colours in a window of
    ``GAP_WINDOW`` of the height around each pixel (its gradient, its noise and the person's shadow
    cast on it are in the covariance); where it is plain (spread under ``PLAIN``), connected regions
    of the person within ``GAP_MATCH`` of it, of at least ``GAP_AREA``, are the backdrop if all of:

    - an edge nearly all around (``GAP_RING_SHARE`` of the ring unlike the backdrop): a gap ends
      where the person begins, a lit patch of a white shirt fades into its folds;
    - its colour is much nearer the backdrop's than the person's own (``GAP_RATIO``; the person's
      colours on the pose's bones, torso and face): the white stripes of a shirt on a white studio
      are the shirt's white, found on its torso too;
    - not on the bones, torso or face (``GAP_ON_BONES``): a white strap on a foot, the eye's white;
      where limbs and body meet (``GAPS``, the face excepted) the bones do not count: the upper arm's
      bone and the torso's side run along the gap between the arm and the body (a strip of a white
      studio's wall there was 72 % on them and kept);
    - the segmentation hesitates somewhere in it (below ``GAP_SURE``): it fills a gap with less
      than certainty, and is certain of a silver clasp on a bag or a boot's grey panel.

    In a clip (``carried``: the frame before's matte carried here, at ``image``'s size), a region the
    frame before had as background over ``GAP_CARRIED`` of it needs only the colour's two guards (the
    backdrop's colour, not on the bones): found once, a gap stays background while it shows the backdrop.

    Measured on composites on plain backdrops (docs/photos.md: the person's own clothes of the
    backdrop's colour are not taken)."""
    labels, figures, model = gap_regions(image, person, tri, segmentation, landmarks, carried)
    keep = np.array([is_gap(f) for f in figures])
    return BackdropGaps(keep[labels], model.index, model.mean, model.inverse)
