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
   sRGB values, as the alpha is. No old background colour survives at the edge (docs/photos.md measures
   the edge's bleed on twelve photos against the multilevel estimate alone).

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

from viewer.photo.backdrop_gaps import backdrop_gaps
from viewer.photo.colour_models import MODEL_RADIUS, ColourModels, colour_models, min_cut
from viewer.photo.held_objects import held_objects
from viewer.photo.pose_masks import person_height
from viewer.photo.trimap import CORE, OUTER, Carried, Trimap, distances, trimap
from viewer.resize import resize

PRIOR = 6.0  # cost (nats) of going against the segmentation at the band's far edge
SOLVE_HEIGHT = 700  # the band is decided where the person is this many pixels tall (or less)
WINDOW_MARGIN = 0.25  # of the person's height: the outline is decided within their box grown this much
WINDOW_SHARE = 0.8  # a window larger than this share of the frame is the frame
EDGE = 0.004  # half-width of the soft edge's band, of the person's height (8 px at 2048)
MIN_EDGE = 1.5  # pixels
HOLE_DEPTH = 1.0  # holes are punched deeper than this many soft-edge half-widths inside the person
OPAQUE = 0.99  # alpha from which a pixel's colour is the person's own (foreground_colours)
EDGE_COLOUR = 3.0  # soft-edge half-widths: the reach of the opaque person's colours into the soft edge
MIN_REACH = 0.05  # the opaque person's weight within that reach below which the multilevel estimate stays
TEMPORAL = 3.0  # nats: the cost of deciding a pixel of a clip's frame against the frame before's decision carried there
HOLE = 9.0  # nats: a pixel of the person this much likelier the local background's colour than its own is background
GAP_EDGE = 0.5  # of the soft edge's half-width: its band on the person's side of a gap (outlined per pixel)


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
    background's colour in a band it cannot tell from the person (docs/photos.md): that
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

    from viewer.resize import height_capped

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
