"""The person's true matte and foreground colours, from a coarse segmentation or a mask file.

A relit person shows the photo's old background wherever the matte keeps it: in the gaps between
an arm and the body, between hair and shoulder, between the feet (which the pose model's 256-px
segmentation fills), and, at any alpha, wherever the photo's colour mixes person and background.
So the matte is decided from the photo, in three steps (docs/photos.md measures each):

1. **The wide band, decided by colour** (:func:`decide_band`). A trimap from the segmentation:
   the person for sure deeper than ``CORE`` of the person's height inside it (except where limbs,
   hair and body meet: ``GAPS``); the background for sure farther than ``OUTER`` outside it. The
   band between holds the gaps between limbs, and is labelled person or background by a minimum cut
   (SciPy's ``maximum_flow``, a maintained solver) of a GrabCut-like energy: local colour models
   (Gaussians of the sure person and of the sure background within ``MODEL_RADIUS``), trusted
   only as far as the two models differ (their Bhattacharyya overlap: where hair and a dark shop
   window look alike, the segmentation decides), the segmentation as a prior, and a
   contrast-sensitive smoothness that puts the outline on the photo's edges. Solved at a size
   where the person is ``SOLVE_HEIGHT`` pixels tall; then, at the frame's resolution, pixels of
   the person whose colour is the local background's beyond doubt are punched out
   (:func:`background_holes`: slivers between the thighs, too thin for the band's resolution),
   and so are the regions of a plain backdrop the person encloses, at any depth and where the
   local models confuse the backdrop with the person beside it (:func:`backdrop_gaps`: between
   the hair and the neck, an arm and the body, the legs; not a white top on a white studio).
2. **The soft edge** (:func:`edge_alpha`): a narrow trimap (``EDGE`` of the person's height either
   side of that outline) solved at the frame's resolution by closed-form matting
   (``pymatting``), chosen against KNN, large-kernel, random-walk and learning-based alpha by
   ``relight bench matte``: hair strands and motion blur come out semi-transparent.
3. **The foreground colours** (:func:`foreground_colours`): at the soft edge and half a band
   inside it, the opaque person's own colour nearby (a normalized Gaussian from deeper inside),
   the alpha carrying the edge's shape; ``pymatting``'s multilevel foreground estimation (Germer
   et al. 2020, ``I = a F + (1 - a) B``) where no opaque person is near. Solved in the photo's
   sRGB values, as the alpha is. No old background colour survives at the edge (issue 42 measured
   the edge's bleed on twelve photos against the multilevel estimate alone: docs/photos.md).

What the person holds or stands on and the segmentation left out (skis, poles) joins the
decided outline before step 2 (:mod:`viewer.photo.held_objects`).

A mask file wins over all of this (:func:`mask_matte`): a soft one is the alpha; a binary one is
the trimap's core, its outline softened by step 2. Either way step 3 gives the colours.
"""

from __future__ import annotations

import contextlib
import io
import time
from dataclasses import dataclass, replace

import numpy as np

from viewer.photo.held_objects import held_objects
from viewer.resize import resize

CORE = 0.02  # of the person's height: deeper than this inside the segmentation is the person for sure
OUTER = 0.012  # of the person's height: farther than this outside it is the background for sure
BONE = 0.01  # the pose's bones, drawn this thick (of the person's height), are sampled for the person's colours
MODEL_RADIUS = 0.03  # local colour models: the Gaussian window's sigma, of the person's height
MODEL_REG = 5e-4  # added to the colour covariances (colours in [0, 1])
COLOUR_CLIP = 10.0  # the colour log-likelihood ratio is bounded to this (nats)
PRIOR = 6.0  # cost (nats) of going against the segmentation at the band's far edge
SMOOTH = 20.0  # contrast-sensitive smoothness between neighbours (GrabCut's gamma; its default is 50)
SOLVE_HEIGHT = 700  # the band is decided where the person is this many pixels tall (or less)
WINDOW_MARGIN = 0.25  # of the person's height: the outline is decided within their box grown this much
WINDOW_SHARE = 0.8  # a window larger than this share of the frame is the frame
EDGE = 0.004  # half-width of the soft edge's band, of the person's height (8 px at 2048)
MIN_EDGE = 1.5  # pixels
FLOW_SCALE = 256  # capacities are integers: costs times this
HOLE_DEPTH = 1.0  # holes are punched deeper than this many soft-edge half-widths inside the person
OPAQUE = 0.99  # alpha from which a pixel's colour is the person's own (foreground_colours)
EDGE_COLOUR = 3.0  # soft-edge half-widths: the reach of the opaque person's colours into the soft edge
MIN_REACH = 0.05  # the opaque person's weight within that reach below which the multilevel estimate stays
TEMPORAL = 3.0  # nats: the cost of deciding a pixel of a clip's frame against the frame before's decision carried there
HOLE = 9.0  # nats: a pixel of the person this much likelier the local background's colour than its own is background
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
GAP_EDGE = 0.5  # of the soft edge's half-width: its band on the person's side of a gap (outlined per pixel)
GAP_CARRIED = 0.5  # a region the frame before had as background over this share of it (a clip's, where the flow holds)
# The pose model's bones (MediaPipe's POSE_CONNECTIONS without the fingers, 17-22, which it guesses)
BONES = ((0, 1), (0, 4), (1, 2), (2, 3), (3, 7), (4, 5), (5, 6), (6, 8), (9, 10), (11, 12), (11, 13), (11, 23),
         (12, 14), (12, 24), (13, 15), (14, 16), (23, 24), (23, 25), (24, 26), (25, 27), (26, 28), (27, 29),
         (27, 31), (28, 30), (28, 32), (29, 31), (30, 32))
TORSO = (11, 12, 24, 23)
FACE = tuple(range(11))  # MediaPipe's face landmarks (nose, eyes, ears, mouth)
# Where limbs, hair and body meet, the segmentation fills the gaps between them (the background
# seen between an arm and the body, between the legs, between hair and shoulder): these polygons
# of landmarks are never the person for sure, whatever their depth inside the segmentation
# ("hips" is the middle of the two hips).
GAPS = ((11, 13, 15, 23), (12, 14, 16, 24),  # each arm and the side of the body
        ("hips", 25, 27, 28, 26),  # between the legs
        (7, 11, 12), (8, 12, 11))  # each ear, its shoulder and the other (hair over the shoulders)


@dataclass(frozen=True)
class Carried:
    """A clip's frame before, brought to this frame along the optical flow (:meth:`viewer.photo.steady.SteadyMaps.carried_matte`):
    its matte ``alpha`` (H, W) in [0, 1] and where the flow holds, ``held`` (H, W) in [0, 1]
    (:func:`viewer.photo.steady.smooth_weight`; :func:`decided_outline` counts only where it is all but 1)."""

    alpha: np.ndarray
    held: np.ndarray
    objects: np.ndarray | None = None  # (H, W) bool: what the frame before was found holding (confirmed or not), carried here


@dataclass(frozen=True)
class Matte:
    """The person's alpha (H, W) float32 in [0, 1] and foreground colours (H, W, 3) float32,
    linear RGB (the photo's colour with the old background taken out; the photo where alpha is 0
    and deeper than half a soft band inside the opaque person), with how it was made (``record``:
    method, seconds) and what of it the person holds (``held``)."""

    alpha: np.ndarray
    foreground: np.ndarray
    record: dict
    held: np.ndarray | None = None  # (H, W) bool: what the person holds or stands on (automatic mattes)
    objects: np.ndarray | None = None  # (H, W) bool: what was found held, kept or not (a clip's next frame confirms it)

    @property
    def body(self) -> np.ndarray:
        """(H, W) bool: the person less what it holds: what frames the networks' view and sizes the
        maps (skis or a barbell wider than the person would shrink the person in both)."""
        person = self.alpha > 0.5
        return person & ~self.held if self.held is not None else person


def person_height(mask: np.ndarray) -> int:
    """Rows the mask spans (at least 1)."""
    rows = np.flatnonzero(mask.any(axis=1))
    return int(rows[-1] - rows[0] + 1) if rows.size else 1


def bones_mask(landmarks: dict, size: tuple[int, int], thickness: int) -> np.ndarray:
    """(H, W) bool: the pose's bones, torso and face drawn at ``size`` = (w, h) from landmarks
    (index -> normalized (x, y))."""
    import cv2

    w, h = size
    out = np.zeros((h, w), np.uint8)
    pts = {i: (int(round(x * w)), int(round(y * h))) for i, (x, y) in landmarks.items()}
    for a, b in BONES:
        if a in pts and b in pts:
            cv2.line(out, pts[a], pts[b], 1, max(1, thickness))
    if all(i in pts for i in TORSO):
        cv2.fillPoly(out, [np.array([pts[i] for i in TORSO], np.int32)], 1)
    face = face_mask(landmarks, size)
    return (out > 0) | face if face is not None else out > 0


def face_mask(landmarks: dict, size: tuple[int, int]) -> np.ndarray | None:
    """(H, W) bool: the convex hull of the pose's face landmarks (``FACE``) at ``size`` = (w, h);
    None when fewer than three of them are seen."""
    import cv2

    w, h = size
    face = [(int(round(x * w)), int(round(y * h))) for i, (x, y) in landmarks.items() if i in FACE]
    if len(face) < 3:
        return None
    out = np.zeros((h, w), np.uint8)
    cv2.fillPoly(out, [cv2.convexHull(np.array(face, np.int32))], 1)
    return out > 0


HEAD_TOP = 1.75  # eye-to-mouth lengths above the eyes: the top of the head (about 1.9), a little inside it
HEAD_CHIN = 0.8  # eye-to-mouth lengths below the mouth: the chin
HEAD_BROWS = 0.4  # eye-to-mouth lengths above the eyes: where the crown begins (the brows; the temples left to the band)
HEAD_WIDE = 0.65  # of the distance between the ears: the head's half-width (1.2 eye-to-mouth lengths without both ears)


def head_mask(landmarks: dict, size: tuple[int, int]) -> np.ndarray | None:
    """(H, W) bool at ``size`` = (w, h): the crown, the ellipse of the head the pose's face landmarks
    give (from ``HEAD_CHIN`` below the mouth to ``HEAD_TOP`` above the eyes, along the face's own up,
    ``HEAD_WIDE`` of the ears' distance to each side) above the brows (``HEAD_BROWS``); None without both
    eyes and the mouth. Within the segmentation it is the person for sure (:func:`trimap`): dark hair against a dark background has the
    background's colours, and the band's colour cut took the top of a head off (a man relit bald)."""
    import cv2

    w, h = size
    pts = {i: np.array([x * w, y * h]) for i, (x, y) in landmarks.items()}
    if not all(i in pts for i in (2, 5, 9, 10)):
        return None
    eyes, mouth = 0.5 * (pts[2] + pts[5]), 0.5 * (pts[9] + pts[10])
    up = eyes - mouth
    length = float(np.linalg.norm(up))
    if length < 1.0:
        return None
    up /= length
    top, chin = eyes + HEAD_TOP * length * up, mouth - HEAD_CHIN * length * up
    wide = HEAD_WIDE * float(np.linalg.norm(pts[7] - pts[8])) if 7 in pts and 8 in pts else 1.2 * length
    centre, tall = 0.5 * (top + chin), 0.5 * float(np.linalg.norm(top - chin))
    out = np.zeros((h, w), np.uint8)
    angle = float(np.degrees(np.arctan2(up[0], -up[1])))  # the face's up from the image's
    cv2.ellipse(out, (int(round(centre[0])), int(round(centre[1]))), (max(int(round(wide)), 1), max(int(round(tall)), 1)),
                angle, 0, 360, 1, -1)
    # above the brows only: the crown and its hair; beside the face and the temples (a turned head's far side,
    # its ears) the segmentation spills over the background, and the band decides there
    xs, ys = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    return (out > 0) & ((xs - eyes[0]) * up[0] + (ys - eyes[1]) * up[1] > HEAD_BROWS * length)


def gaps_mask(landmarks: dict, size: tuple[int, int]) -> np.ndarray:
    """(H, W) bool: the ``GAPS`` polygons at ``size`` = (w, h) whose landmarks are all seen."""
    import cv2

    w, h = size
    pts = {i: (x * w, y * h) for i, (x, y) in landmarks.items()}
    if 23 in pts and 24 in pts:
        pts["hips"] = tuple(0.5 * (a + b) for a, b in zip(pts[23], pts[24]))
    out = np.zeros((h, w), np.uint8)
    for polygon in GAPS:
        if all(i in pts for i in polygon):
            cv2.fillPoly(out, [np.round([pts[i] for i in polygon]).astype(np.int32)], 1)
    return out > 0


def distances(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(distance inside, distance outside) of every pixel to the mask's outline, pixels."""
    import cv2

    m = mask.astype(np.uint8)
    return cv2.distanceTransform(m, cv2.DIST_L2, 5), cv2.distanceTransform(1 - m, cv2.DIST_L2, 5)


def local_gaussians(image: np.ndarray, weight: np.ndarray, sigma: float, at: np.ndarray, reg: float = MODEL_REG):
    """Mean (n, 3), covariance (n, 3, 3) (``reg`` added to its diagonal) and the weights' sum (n,)
    of ``image``'s colours weighted by ``weight`` in a Gaussian window of ``sigma`` pixels, at the
    pixels ``at`` (H, W) bool. The window's sums run on the image shrunk to a quarter of sigma per
    pixel and come back bilinearly."""
    import cv2

    h, w = weight.shape
    factor = max(1, int(sigma / 4))
    size = (max(w // factor, 1), max(h // factor, 1))
    s = sigma * size[0] / w
    k = 2 * int(np.ceil(3 * s)) + 1
    x = image.astype(np.float32)
    iu, ju = np.triu_indices(3)
    moments = np.concatenate([x, x[..., iu] * x[..., ju], np.ones((h, w, 1), np.float32)], axis=-1) * weight[..., None]
    small = cv2.GaussianBlur(resize(moments, size, "area"), (k, k), s, borderType=cv2.BORDER_REFLECT)
    sums = resize(small.reshape(size[1], size[0], -1), (w, h), "linear")[at]
    total = np.maximum(sums[:, 9:10], 1e-6)
    mean = sums[:, :3] / total
    second = sums[:, 3:9] / total
    cov = np.empty((len(mean), 3, 3), np.float32)
    for n, (i, j) in enumerate(zip(iu, ju)):
        cov[:, i, j] = cov[:, j, i] = second[:, n] - mean[:, i] * mean[:, j]
    cov += reg * np.eye(3, dtype=np.float32)
    return mean, cov, sums[:, 9]


def inverse_3x3(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(inverses (n, 3, 3), log absolute determinants (n,)) of 3x3 matrices (n, 3, 3), by the
    adjugate in float64: as NumPy's ``inv`` and ``slogdet`` give them, which took 0.09 s a frame on a
    clip's band (LAPACK's cost per matrix)."""
    a = m.astype(np.float64)
    adj = np.empty_like(a)
    adj[:, 0, 0] = a[:, 1, 1] * a[:, 2, 2] - a[:, 1, 2] * a[:, 2, 1]
    adj[:, 1, 0] = a[:, 1, 2] * a[:, 2, 0] - a[:, 1, 0] * a[:, 2, 2]
    adj[:, 2, 0] = a[:, 1, 0] * a[:, 2, 1] - a[:, 1, 1] * a[:, 2, 0]
    adj[:, 0, 1] = a[:, 0, 2] * a[:, 2, 1] - a[:, 0, 1] * a[:, 2, 2]
    adj[:, 0, 2] = a[:, 0, 1] * a[:, 1, 2] - a[:, 0, 2] * a[:, 1, 1]
    adj[:, 1, 1] = a[:, 0, 0] * a[:, 2, 2] - a[:, 0, 2] * a[:, 2, 0]
    adj[:, 1, 2] = a[:, 0, 2] * a[:, 1, 0] - a[:, 0, 0] * a[:, 1, 2]
    adj[:, 2, 1] = a[:, 0, 1] * a[:, 2, 0] - a[:, 0, 0] * a[:, 2, 1]
    adj[:, 2, 2] = a[:, 0, 0] * a[:, 1, 1] - a[:, 0, 1] * a[:, 1, 0]
    det = a[:, 0, 0] * adj[:, 0, 0] + a[:, 0, 1] * adj[:, 1, 0] + a[:, 0, 2] * adj[:, 2, 0]
    return (adj / det[:, None, None]).astype(m.dtype), np.log(np.abs(det)).astype(m.dtype)


@dataclass(frozen=True)
class ColourModels:
    """Local Gaussian colour models of the sure person and the sure background at some pixels of
    an image (``index`` (H, W): the pixel's row in the arrays, -1 where there is none): means
    (n, 3), inverse covariances (n, 3, 3) and log-determinants (n,), person's then background's,
    and the trust (n,) in telling them apart, 1 minus their Bhattacharyya coefficient (0 where
    the two look alike)."""

    index: np.ndarray
    mean: tuple
    inverse: tuple
    logdet: tuple
    trust: np.ndarray

    def evidence(self, colours: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """The log-likelihood ratio person / background of ``colours`` (m, 3) under the models of
        the pixels ``rows`` (m,), bounded by ``COLOUR_CLIP`` and scaled by the trust."""
        ll = []
        for mean, inv, logdet in zip(self.mean, self.inverse, self.logdet):
            d = colours.astype(np.float32) - mean[rows]
            ll.append(-0.5 * np.einsum("ni,nij,nj->n", d, inv[rows], d) - 0.5 * logdet[rows])
        return (np.clip(ll[0] - ll[1], -COLOUR_CLIP, COLOUR_CLIP) * self.trust[rows]).astype(np.float32)


def colour_models(image: np.ndarray, person: np.ndarray, background: np.ndarray, at: np.ndarray,
                  sigma: float) -> ColourModels:
    """The :class:`ColourModels` of the ``person`` and ``background`` pixels' colours (Gaussian
    windows of ``sigma`` pixels) at the pixels ``at``."""
    index = np.full(at.shape, -1, np.int64)
    index[at] = np.arange(int(at.sum()))
    mean_p, cov_p, _ = local_gaussians(image, person.astype(np.float32), sigma, at)
    mean_b, cov_b, _ = local_gaussians(image, background.astype(np.float32), sigma, at)
    (inverse_p, logdet_p), (inverse_b, logdet_b) = inverse_3x3(cov_p), inverse_3x3(cov_b)
    inverse_mid, logdet_mid = inverse_3x3(0.5 * (cov_p + cov_b))
    d = mean_p - mean_b
    bhattacharyya = np.einsum("ni,nij,nj->n", d, inverse_mid, d) / 8 + 0.5 * (logdet_mid - 0.5 * (logdet_p + logdet_b))
    return ColourModels(index, (mean_p, mean_b), (inverse_p, inverse_b), (logdet_p, logdet_b),
                        (1.0 - np.exp(-np.maximum(bhattacharyya, 0.0))).astype(np.float32))


def min_cut(image: np.ndarray, person: np.ndarray, background: np.ndarray, cost_person: np.ndarray,
            cost_background: np.ndarray, smooth: float = SMOOTH) -> np.ndarray:
    """(H, W) bool: the labelling of minimum energy, person where ``person``, background where
    ``background``, and between them the sum of each pixel's cost of its label (``cost_*`` at the
    free pixels, (n,)) and, between 8-neighbours labelled differently,
    ``smooth / distance * exp(-beta |I_p - I_q|^2)`` (Boykov and Jolly's contrast term, beta as
    in GrabCut): a minimum s-t cut, SciPy's ``maximum_flow`` (Dinic)."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import breadth_first_order, maximum_flow

    h, w = person.shape
    free = ~person & ~background
    n = int(free.sum())
    out = person.copy()
    if n == 0:
        return out
    ids = np.full((h, w), -1, np.int64)
    ids[free] = np.arange(n)
    cost_p = np.zeros((h, w), np.float64)
    cost_b = np.zeros((h, w), np.float64)
    cost_p[free], cost_b[free] = cost_person, cost_background
    img = image.astype(np.float32)
    pairs = []
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
        p = (slice(0, h - dy), slice(max(0, -dx), w - max(0, dx)))
        q = (slice(dy, h), slice(max(0, dx), w + min(0, dx)))
        pairs.append((p, q, ((img[p] - img[q]) ** 2).sum(-1), 1.0 / np.hypot(dy, dx)))
    near = [d2[free[p] | free[q]] for p, q, d2, _ in pairs]
    beta = 1.0 / max(2.0 * float(np.mean(np.concatenate(near))), 1e-12)
    rows, cols, caps = [], [], []
    for p, q, d2, inv_dist in pairs:
        weight = smooth * inv_dist * np.exp(-beta * d2)
        fp, fq = free[p], free[q]
        both = fp & fq
        rows += [ids[p][both], ids[q][both]]
        cols += [ids[q][both], ids[p][both]]
        caps += [weight[both], weight[both]]
        # a free pixel beside a fixed one pays the pair's weight for the other label
        for here, there, fixed_person, fixed_background in ((p, q, person[q], background[q]), (q, p, person[p], background[p])):
            alone = free[here] & ~free[there]
            cost_b[here] += np.where(alone & fixed_person, weight, 0.0)
            cost_p[here] += np.where(alone & fixed_background, weight, 0.0)
    cp, cb = cost_p[free], cost_b[free]
    low = np.minimum(cp, cb)
    source, sink = n, n + 1
    idx = np.arange(n)
    rows += [np.full(n, source), idx]
    cols += [idx, np.full(n, sink)]
    caps += [cb - low, cp - low]  # cutting source -> p labels p background; p -> sink labels it person
    r, c = np.concatenate(rows), np.concatenate(cols)
    cap = np.round(np.concatenate(caps) * FLOW_SCALE).astype(np.int64)
    keep = cap > 0
    graph = csr_matrix((np.minimum(cap[keep], 2 ** 30).astype(np.int32), (r[keep], c[keep])), shape=(n + 2, n + 2))
    graph.sum_duplicates()
    flow = maximum_flow(graph, source, sink, method="dinic").flow
    residual = (graph - flow).tocsr()
    residual.data = np.maximum(residual.data, 0)
    residual.eliminate_zeros()
    reached = np.zeros(n + 2, bool)
    reached[breadth_first_order(residual, source, directed=True, return_predecessors=False)] = True
    out[free] = reached[:n]
    return out


@dataclass(frozen=True)
class Trimap:
    """The segmentation's trimap (H, W) bool each: the person for sure, the pixels its colours are
    sampled from (the sure person and its bones), the background for sure; the band is the rest.
    ``inside``, ``outside``: each pixel's distance to the segmentation's outline; ``height`` the
    person's, pixels."""

    sure_person: np.ndarray
    samples: np.ndarray
    sure_background: np.ndarray
    inside: np.ndarray
    outside: np.ndarray
    height: int

    @property
    def band(self) -> np.ndarray:
        return ~self.sure_person & ~self.sure_background


def trimap(segmentation: np.ndarray, landmarks: dict) -> Trimap:
    """The trimap of a soft segmentation (H, W) and the pose's landmarks (index -> normalized (x, y))."""
    h, w = segmentation.shape
    seg = segmentation > 0.5
    height = person_height(seg)
    inside, outside = distances(seg)
    sure_person = (inside > CORE * height) & ~gaps_mask(landmarks, (w, h))
    head = head_mask(landmarks, (w, h))
    if head is not None:  # the head within the segmentation: its hair kept against a background of its colour
        sure_person |= head & seg
    # the person's colours also come from its bones (a thin limb has no deep pixels)
    samples = sure_person | (bones_mask(landmarks, (w, h), int(round(BONE * height))) & seg)
    return Trimap(sure_person, samples, outside > OUTER * height, inside, outside, height)


def decide_band(image: np.ndarray, tri: Trimap, models: ColourModels, carried: Carried | None = None) -> np.ndarray:
    """(H, W) bool: the person at ``image``'s size (float RGB in [0, 1]), the trimap's band
    labelled by :func:`min_cut` with the colour ``models`` (which cover the band); ``carried``: a
    clip's frame before, its matte carried here along the flow (at ``image``'s size): where the flow
    holds, going against its decision costs ``TEMPORAL`` nats, except that it never pulls towards the
    person a pixel outside this frame's own segmentation: a wrong flow, or a piece of the old
    background the frame before kept, would otherwise be handed on from frame to frame (kept for a few
    frames and then dropped: pieces that pop in and out). Inside it, it still holds an outline the
    frame's colours leave open (dark hair against a dark background) as it was a frame ago."""
    band = tri.band
    if not band.any() or not tri.sure_background.any():
        return tri.inside > 0
    llr = models.evidence(image[band], models.index[band])
    cost_person = np.maximum(-llr, 0) + PRIOR * np.minimum(tri.outside[band] / (OUTER * tri.height), 1.0)
    cost_background = np.maximum(llr, 0) + PRIOR * np.minimum(tri.inside[band] / (CORE * tri.height), 1.0)
    if carried is not None:
        weight = TEMPORAL * carried.held[band]
        refused = tri.outside[band] > 0  # this frame's segmentation calls it background
        pull_person = np.where(refused, 0.0, weight * carried.alpha[band])
        cost_person += weight * (1.0 - carried.alpha[band])
        cost_background += pull_person
    person = min_cut(image, tri.sure_person, tri.sure_background, cost_person, cost_background)
    return keep_connected(person, tri.sure_person)


def background_holes(image: np.ndarray, person: np.ndarray, models: ColourModels, depth: float) -> np.ndarray:
    """(H, W) bool at ``image``'s size (float RGB in [0, 1], finer than the models'): pixels of
    ``person`` deeper than ``depth`` pixels inside it whose colour is the local background's
    beyond doubt (evidence below ``-HOLE``), each judged by the models of its nearest model
    pixel: slivers of background between the thighs or beside an arm, too thin for the band's
    resolution or deep in a segmentation that filled them (nearer the outline, the soft edge
    decides)."""
    h, w = person.shape
    mh, mw = models.index.shape
    ys, xs = np.nonzero(distances(person)[0] > depth)
    rows = models.index[np.minimum((ys * mh) // h, mh - 1), np.minimum((xs * mw) // w, mw - 1)]
    known = rows >= 0
    holes = np.zeros((h, w), bool)
    holes[ys[known], xs[known]] = models.evidence(image[ys[known], xs[known]], rows[known]) < -HOLE
    return holes


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


def keep_connected(mask: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    """The connected parts of ``mask`` (8-neighbours) that hold a seed pixel."""
    import cv2

    count, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    if count <= 2:
        return mask
    keep = np.zeros(count, bool)
    keep[np.unique(labels[seeds & mask])] = True
    keep[0] = False
    return keep[labels]


def edge_alpha(photo: np.ndarray, person: np.ndarray, half_width: float, holes: np.ndarray | None = None,
               solve=None, gaps: np.ndarray | None = None) -> np.ndarray:
    """(H, W) float32 alpha: ``person`` (bool) less its ``holes`` and ``gaps`` (background for
    sure), with its outline softened in a band of ``half_width`` pixels either side, over the
    band's bounding box, by ``solve(image, trimap)`` (one of pymatting's alpha solvers;
    closed-form matting when None). A gap's outline is found to the pixel (:func:`backdrop_gaps`):
    the band on the person's side of it is ``GAP_EDGE`` as wide (a full band there takes the
    person's edge for mixed, cut 0.213 against 0.197 on a composite)."""
    if solve is None:
        from pymatting import estimate_alpha_cf as solve

    background = np.zeros(person.shape, bool)
    for mask in (holes, gaps):
        if mask is not None:
            background |= mask
    whole = person & ~holes if holes is not None else person  # the outline the gaps are not part of
    person = person & ~background
    inside, outside = distances(person)
    known = np.where(inside > half_width, 1.0, np.where(outside > half_width, 0.0, 0.5))
    known[background] = 0.0
    if gaps is not None and gaps.any():
        far = (distances(gaps)[1] > GAP_EDGE * half_width) & (distances(whole)[0] > half_width)
        known[(known == 0.5) & person & far] = 1.0
    unknown = known == 0.5
    alpha = known.astype(np.float32)
    if not unknown.any() or (known == 0).sum() == 0 or (known == 1).sum() == 0:
        return person.astype(np.float32)
    rows, cols = np.flatnonzero(unknown.any(axis=1)), np.flatnonzero(unknown.any(axis=0))
    pad = int(np.ceil(half_width)) + 2
    y0, y1 = max(rows[0] - pad, 0), min(rows[-1] + pad + 1, person.shape[0])
    x0, x1 = max(cols[0] - pad, 0), min(cols[-1] + pad + 1, person.shape[1])
    box = (slice(y0, y1), slice(x0, x1))
    tri = known[box]
    if (tri == 0).any() and (tri == 1).any():
        image = np.clip(photo[box].astype(np.float64) / 255.0, 0.0, 1.0)
        with contextlib.redirect_stdout(io.StringIO()):  # pymatting prints its preconditioner's retries
            alpha[box] = np.clip(solve(image, tri), 0.0, 1.0)
    return alpha


def foreground_colours(image: np.ndarray, alpha: np.ndarray, half_width: float) -> np.ndarray:
    """(H, W, 3) float32: the person's own colours F in ``I = a F + (1 - a) B`` where the matte is
    soft; the image where it is opaque. ``image`` in the values ``alpha`` was solved in (the photo's
    sRGB-encoded values, as :func:`edge_alpha` solves it): F solved in other values (linear) than
    its alpha goes below zero where a dark person meets a bright background, and the edge turns black.

    F is the opaque person's colour nearby (a normalized Gaussian of ``EDGE_COLOUR`` soft-edge
    half-widths over the pixels at least ``OPAQUE``): the soft edge is where the photo's colour is
    least the person's, and the alpha carries its shape (hair strands, motion blur). Measured
    against pymatting's multilevel estimate (Germer et al. 2020) alone, which keeps the old
    background's colour in a band it cannot tell from the person (docs/photos.md, issue 42): that
    estimate is what is left where no opaque person is within reach (a strand far from the head)."""
    from pymatting import estimate_foreground_ml

    from viewer.photo.detail import masked_lowpass

    soft = (alpha > 0) & (alpha < OPAQUE)
    out = image.astype(np.float32).copy()
    if not soft.any():
        return out
    rows, cols = np.flatnonzero(soft.any(axis=1)), np.flatnonzero(soft.any(axis=0))
    pad = int(np.ceil(3 * EDGE_COLOUR * half_width)) + 8
    y0, y1 = max(rows[0] - pad, 0), min(rows[-1] + pad + 1, alpha.shape[0])
    x0, x1 = max(cols[0] - pad, 0), min(cols[-1] + pad + 1, alpha.shape[1])
    box = (slice(y0, y1), slice(x0, x1))
    scale = max(float(image[box].max()), 1e-6)  # the estimate works on [0, 1] images
    fg = estimate_foreground_ml((image[box] / scale).astype(np.float32), alpha[box].astype(np.float32)) * scale
    depth, _ = distances(alpha[box] >= OPAQUE)  # how deep inside the opaque person
    sigma = EDGE_COLOUR * half_width
    deep = (depth > half_width).astype(np.float32)
    near = masked_lowpass(out[box], deep, sigma)
    reach = masked_lowpass(deep, np.ones_like(deep), sigma) > MIN_REACH
    own = np.clip(depth / half_width, 0.0, 1.0)[..., None]  # the photo's own colour, from half a band inside
    edge = np.where(soft[box][..., None], np.maximum(fg, 0.0), out[box])
    edge = np.where(reach[..., None], near, edge)
    out[box] = np.where((alpha[box] > 0)[..., None], own * out[box] + (1.0 - own) * edge, out[box])
    return out


def solve_window(segmentation: np.ndarray) -> tuple[slice, slice] | None:
    """(rows, columns) of the frame the outline is decided in: the person's box (``segmentation``
    over one half) grown by ``WINDOW_MARGIN`` of their height on every side, its corner on a multiple of
    8 pixels; None where that is most of the frame (``WINDOW_SHARE``) or the person is taller than
    ``SOLVE_HEIGHT`` (the frame is brought to that height first, and a window would move the pixel grid
    it is brought to): the whole frame is solved."""
    seg = segmentation > 0.5
    if not seg.any():
        return None
    h, w = seg.shape
    rows, cols = np.flatnonzero(seg.any(axis=1)), np.flatnonzero(seg.any(axis=0))
    if rows[-1] - rows[0] + 1 > SOLVE_HEIGHT:
        return None
    margin = int(np.ceil(WINDOW_MARGIN * (rows[-1] - rows[0] + 1)))
    y0, x0 = max(rows[0] - margin, 0) // 8 * 8, max(cols[0] - margin, 0) // 8 * 8
    y1, x1 = min(rows[-1] + 1 + margin, h), min(cols[-1] + 1 + margin, w)
    if (y1 - y0) * (x1 - x0) > WINDOW_SHARE * h * w:
        return None
    return slice(y0, y1), slice(x0, x1)


def decided_outline(photo: np.ndarray, person, carried: Carried | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Step 1 of the automatic matte: (the person (H, W) bool at ``photo``'s size, its band
    decided by colour (and by the frame before's, ``carried``, in a clip); the background's holes
    in it; the plain backdrop it encloses (:func:`backdrop_gaps`); the soft edge's half-width, pixels).

    Decided in the window around the person (:func:`solve_window`), the rest of the frame being sure
    background: everything it decides lies within ``OUTER`` of the person's height of them, and what
    it reads (the colour models' windows, the backdrop's) within three of its sigmas. A person a fifth of a
    1280x720 frame took 0.40 s a frame decided over the whole frame."""
    window = solve_window(person.segmentation)
    if window is None:
        return _decided_outline(photo, person, carried)
    rows, cols = window
    h, w = photo.shape[:2]
    x0, y0, cw, ch = cols.start, rows.start, cols.stop - cols.start, rows.stop - rows.start
    landmarks = {i: ((x * w - x0) / cw, (y * h - y0) / ch) for i, (x, y) in person.landmarks.items()}
    inside = replace(person, segmentation=person.segmentation[window], landmarks=landmarks)
    carried = Carried(carried.alpha[window], carried.held[window]) if carried is not None else None  # (objects: not read here)
    *masks, half_width = _decided_outline(np.ascontiguousarray(photo[window]), inside, carried)
    whole = []
    for mask in masks:
        out = np.zeros((h, w), bool)
        out[window] = mask
        whole.append(out)
    return (*whole, half_width)


def _decided_outline(photo: np.ndarray, person, carried: Carried | None = None
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    from scipy.ndimage import binary_fill_holes

    from viewer.resize import height_capped, resize

    h, w = photo.shape[:2]
    height = person_height(person.segmentation > 0.5)
    size = height_capped((w, h), height, SOLVE_HEIGHT)
    segmentation = resize(person.segmentation, size)
    tri = trimap(segmentation, person.landmarks)
    small = resize(photo, size).astype(np.float32) / 255.0
    models = colour_models(small, tri.samples, tri.sure_background, ~tri.sure_background, MODEL_RADIUS * tri.height)
    if carried is not None:
        carried = Carried(resize(carried.alpha, size), (resize(carried.held.astype(np.float32), size) > 0.99).astype(np.float32))
    person_small = decide_band(small, tri, models, carried)
    decided = resize(person_small.astype(np.float32), (w, h)) > 0.5
    half_width = max(MIN_EDGE, EDGE * height)
    image = photo.astype(np.float32) / 255.0
    # the gaps are looked for in the person with the background it encloses: a strip between an arm
    # and the body the band already decided background (narrower than the soft edge's band on both
    # sides) was otherwise left to the soft edge, which filled it with the person
    enclosed = binary_fill_holes(person_small)
    gaps = backdrop_gaps(small, enclosed, tri, segmentation, person.landmarks, carried).at(
        image, resize(enclosed.astype(np.float32), (w, h)) > 0.5)
    return decided, background_holes(image, decided, models, HOLE_DEPTH * half_width), gaps, half_width


def automatic_matte(photo: np.ndarray, person, carried: Carried | None = None) -> Matte:
    """The matte of ``photo`` (H, W, 3) uint8 sRGB from the pose model's :class:`viewer.photo.segmentation.Person`
    (``carried``: a clip's frame before, :func:`decide_band`)."""
    from viewer.files.imageio import srgb_to_linear

    t0 = time.perf_counter()
    decided, holes, gaps, half_width = decided_outline(photo, person, carried)
    found = held_objects(photo, decided, person.landmarks, person_height(decided)) & ~decided
    held = confirmed(found, carried.objects) if carried is not None and carried.objects is not None else found
    decided = decided | held
    t1 = time.perf_counter()
    alpha = edge_alpha(photo, decided, half_width, holes, gaps=gaps)
    t2 = time.perf_counter()
    foreground = srgb_to_linear(foreground_colours(photo.astype(np.float32) / 255.0, alpha, half_width))
    t3 = time.perf_counter()
    return Matte(alpha, foreground, {"method": "automatic: pose segmentation, colour min cut, closed-form edge",
                                     "holes_px": int(holes.sum()), "gaps_px": int(gaps.sum()),
                                     "held_px": int(held.sum()), "held_found_px": int(found.sum()),
                                     "seconds": {"band": round(t1 - t0, 3), "edge": round(t2 - t1, 3),
                                                 "foreground": round(t3 - t2, 3)}}, held, found)


CONFIRM_REACH = 0.01  # of the frame's longer side: how near the frame before's find an object found again must be


def confirmed(found: np.ndarray, before: np.ndarray) -> np.ndarray:
    """(H, W) bool: the objects of ``found`` (a clip's frame's held objects, :mod:`viewer.photo.held_objects`)
    that the frame before found too (``before``, carried here along the flow), within ``CONFIRM_REACH``.
    Found frame by frame, an object came and went: the crowd clip's 60 frames had objects in 7 frames,
    6 of them alone (a shoe's shard, a piece of a sign); an object is kept from its second frame in a row."""
    import cv2

    if not found.any() or not before.any():
        return np.zeros_like(found)
    reach = max(1, int(round(CONFIRM_REACH * max(found.shape))))
    near = cv2.dilate(before.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach + 1,) * 2)) > 0
    count, labels = cv2.connectedComponents(found.astype(np.uint8), connectivity=8)
    keep = np.zeros(count, bool)
    keep[np.unique(labels[found & near])] = True
    keep[0] = False
    return keep[labels]


BINARY_GREY = 0.25  # a mask with fewer grey pixels (2 % to 98 %) than this share of its outline is binary


def mask_matte(photo: np.ndarray, mask: np.ndarray) -> Matte:
    """The matte of a mask file (H, W) in [0, 1]: a soft mask is the alpha as it is; a binary one
    is the trimap's core, its outline softened by :func:`edge_alpha`. Foreground colours either way."""
    from viewer.files.imageio import srgb_to_linear

    t0 = time.perf_counter()
    person = mask > 0.5
    inside, _ = distances(person)
    binary = int(((mask > 0.02) & (mask < 0.98)).sum()) < BINARY_GREY * int(((inside > 0) & (inside <= 1)).sum())
    half_width = max(MIN_EDGE, EDGE * person_height(person))
    alpha = edge_alpha(photo, person, half_width) if binary else mask.astype(np.float32)
    t1 = time.perf_counter()
    foreground = srgb_to_linear(foreground_colours(photo.astype(np.float32) / 255.0, alpha, half_width))
    return Matte(alpha, foreground, {"method": "mask file, " + ("binary: closed-form edge" if binary else "soft: as given"),
                                     "seconds": {"edge": round(t1 - t0, 3), "foreground": round(time.perf_counter() - t1, 3)}})
