"""The photo's own lighting, fitted to the photo: what relighting divides out.

The inverse-rendering network guesses the photo's lights, but its guess need not explain the
photo (on real photos most of its lights point straight up, and the render under them is 0.6 to
4.7 times the photo's brightness). The quotient image (:mod:`viewer.photo.detail`) divides the photo by
the shading under these lights, so they must reproduce the photo. They are fitted here:

1. ``BASIS`` area lights spread over the whole sphere (a Fibonacci sphere, each with the sigma of
   its cell, as median cut gives a region of that spread) are rendered by the GL engine on the
   bundle's maps, once, with their shadows: per light the image
   ``b_l = V_l (A S_diff_l + S_spec_l)`` per unit intensity;
2. the light intensities are the non-negative least-squares fit of ``sum_l I_l b_l`` to the
   photo's low-pass inside the person, in luminance (non-negative: light only adds; colourless:
   see below),
   with a small ridge term that shares light between neighbouring directions instead of
   picking one, and iteratively reweighted (Huber) so that what the model cannot explain
   (a logo, a shadow from something outside the photo) does not pull the lights;
3. pixels that cannot inform the fit are left out: the matte's edge, and clipped highlights
   (any channel at 98 % of white or above), where the photo no longer says how bright the light is.
   Dark clothes stay in: their residuals are small in linear units, so they barely pull. The
   caller may weigh pixels: inference gives the face, fitted at its own resolution
   (:mod:`viewer.photo.face`), a quarter of the fit, since the networks' nearly flat normals elsewhere
   cannot tell a light from above from one in front, and the face's form can.
Lights that end with no intensity are dropped (leave out what contributes nothing).

The lights are colourless (each light's intensity the same in every channel). A photo comes
white-balanced by its camera, so the light on the person is, over all, about grey; and the
colours a fit per channel gives the lights are mostly the networks' albedo being off colour, not
the light's: a cream blouse read as grey made the light green (the blouse, divided by it, came out
pink), and after the lights' overall colour was taken out their colours per direction still gave a
white-studio photo's person a blue cast of 0.015 in u'v' and a skier's white collar a cyan one.
Fitted per channel (white-balanced), by their reach on the person, or in luminance, the relit error
on held-out synthetic pairs, whose maps are coloured and which no camera balanced, was 0.2653,
0.2623 and 0.2608 (docs/photos.md): the colour per direction bought nothing there either. The
quotient image then keeps the photo's colours as the person's (:mod:`viewer.photo.detail`).
"""

from __future__ import annotations

import time

import numpy as np

from viewer.lighting.light_size import cap_sigma
from viewer.photo.detail import luminance
from viewer.scene.area_lights import AreaLights

BASIS = 48  # directions on the sphere
SATURATED = 0.98  # sRGB value from which a photo pixel is a clipped highlight
RIDGE = 1e-3  # of the Gram matrix's mean diagonal
HUBER = 1.345  # in robust standard deviations (95 % efficiency for Gaussian noise)
IRLS_STEPS = 4
MAX_SAMPLES = 40_000  # pixels used for the fit (a regular subsample of the valid ones)


def basis_lights(n: int = BASIS) -> AreaLights:
    """``n`` unit-intensity lights on a Fibonacci sphere, each as large as the map's lights' own rule
    makes a light spread evenly over its cell, a cap of solid angle 4 pi / n
    (:func:`viewer.lighting.light_size.cap_sigma`)."""
    from viewer.lighting.lightfit.fit import fibonacci_sphere

    directions = fibonacci_sphere(n).astype(np.float32)
    sigma = cap_sigma(float(np.arccos(1.0 - 2.0 / n)))  # each light owns a cap of solid angle 4 pi / n
    return AreaLights(directions, np.full(n, sigma, np.float32), np.ones((n, 3), np.float32))


def fit_mask(scene, photo: np.ndarray, erode: int = 2) -> np.ndarray:
    """Pixels of the work frame that inform the fit: inside the eroded mask, not clipped."""
    import cv2

    from viewer.files.imageio import linear_to_srgb

    inside = cv2.erode(scene.mask.astype(np.uint8), np.ones((2 * erode + 1, 2 * erode + 1), np.uint8)) > 0
    clipped = (linear_to_srgb(photo) >= SATURATED).any(axis=-1)
    return inside & ~clipped


def basis_images(engine, lights: AreaLights, pixels: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """(K, P, 3): each light's image ``V (A S_diff + S_spec)`` per unit intensity at ``pixels``
    (rows, cols of the work frame), rendered by ``engine`` with its soft shadows."""
    engine.set_lights(lights)
    engine.set_visibility("soft")
    engine.render()
    albedo = engine.scene.albedo[pixels]
    out = np.zeros((len(lights), pixels[0].size, 3), np.float32)
    for i in range(len(lights)):
        r = engine.output.read_light(i)
        v = r["visibility_soft"][pixels]
        out[i] = v[:, None] * (albedo * r["diffuse"][pixels][:, None] + r["specular"][pixels][:, None])
    return out


def nnls_ridge(b: np.ndarray, t: np.ndarray, w: np.ndarray, ridge: float) -> np.ndarray:
    """argmin_{x >= 0} sum_p w_p (b_p . x - t_p)^2 + ridge mean(diag G) |x|^2 for b (P, K)."""
    from scipy.linalg import cholesky, solve_triangular
    from scipy.optimize import nnls

    bw = b * w[:, None]
    gram = b.T @ bw
    gram += np.eye(gram.shape[0]) * ridge * max(float(np.mean(np.diag(gram))), 1e-30)
    h = bw.T @ t
    upper = cholesky(gram, lower=False)  # gram = U^T U
    # |U x - U^-T h|^2 = x^T G x - 2 h^T x + const
    x, _ = nnls(upper, solve_triangular(upper, h, trans="T"), maxiter=50 * gram.shape[0])
    return x


def fit_photo_lights(engine, photo: np.ndarray, valid: np.ndarray, n: int = BASIS,
                     weight: np.ndarray | None = None) -> tuple[AreaLights, dict]:
    """The photo's lights, colourless: ``engine`` renders the scene's maps (work frame); ``photo``
    (H, W, 3) linear, the target (already low-passed to the maps' level of detail), fitted in
    luminance; ``valid`` the pixels that count, ``weight`` (H, W) how much each counts (default: all
    alike). Returns the lights (zero ones dropped) and a record of the fit."""
    t0 = time.perf_counter()
    rows, cols = np.nonzero(valid)
    if rows.size > MAX_SAMPLES:
        keep = np.linspace(0, rows.size - 1, MAX_SAMPLES).astype(int)
        rows, cols = rows[keep], cols[keep]
    prior = np.ones(rows.size) if weight is None else np.asarray(weight, np.float64)[rows, cols]
    basis = basis_lights(n)
    # in luminance; the least squares must not fail on a stray non-finite texel (a degenerate normal or depth)
    b = np.nan_to_num(luminance(basis_images(engine, basis, (rows, cols))).T.astype(np.float64), nan=0.0, posinf=0.0,
                      neginf=0.0)  # (P, K)
    t_render = time.perf_counter() - t0
    target = np.nan_to_num(luminance(photo[rows, cols]).astype(np.float64), nan=0.0, posinf=0.0, neginf=0.0)  # (P,)
    w = prior.copy()
    for _ in range(IRLS_STEPS):
        x = nnls_ridge(b, target, w, RIDGE)
        r = b @ x - target
        scale = 1.4826 * np.median(np.abs(r)) + 1e-12
        w = prior * np.minimum(1.0, HUBER * scale / np.maximum(np.abs(r), 1e-30))
    intensity = np.repeat(x[:, None], 3, axis=1)
    model = b @ x
    keep = x > 1e-6 * max(float(x.max()), 1e-30)
    if not keep.any():  # a black photo has no light to fit: one light from the front, at zero, keeps the light file valid
        keep[np.argmax(basis.direction[:, 2])] = True
    lights = AreaLights(basis.direction[keep], basis.sigma[keep], intensity[keep].astype(np.float32))
    record = {
        "method": f"non-negative least squares over {n} directions (Fibonacci sphere), Huber-reweighted, in luminance",
        "basis": n, "lights": int(keep.sum()), "pixels": int(rows.size),
        "relative_error": float(np.abs(model - target).mean() / max(float(np.abs(target).mean()), 1e-12)),
        "seconds_render": round(t_render, 3), "seconds": round(time.perf_counter() - t0, 3),
    }
    return lights, record

