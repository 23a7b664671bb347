"""Local colour models of the sure person and the sure background (Gaussians in a window) and the
minimum cut that labels a band between them: the matte's decision by colour (:mod:`viewer.photo.matting`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewer.resize import resize

MODEL_RADIUS = 0.03  # local colour models: the Gaussian window's sigma, of the person's height
MODEL_REG = 5e-4  # added to the colour covariances (colours in [0, 1])
COLOUR_CLIP = 10.0  # the colour log-likelihood ratio is bounded to this (nats)
SMOOTH = 20.0  # contrast-sensitive smoothness between neighbours (GrabCut's gamma; its default is 50)
FLOW_SCALE = 256  # capacities are integers: costs times this


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
