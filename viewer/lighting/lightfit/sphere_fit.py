"""The instant and fast fits' Step 2 in numpy: directions and log-intensities moved by Adam on the sphere.

The loss is the paper's L_diff + L_spec: the L1 in sRGB between the lights' and the map's diffuse
and specular shading of the sphere view under each of its rotations. Its gradient is written out
(the lobes' slopes come from :class:`.sphere_lobes.SphereLobes`), which keeps torch out of the
default fit; ``tests/test_lightfit.py`` checks loss and gradient against torch's autograd of the
same loss.
"""

from __future__ import annotations

import numpy as np

from viewer.files.imageio import SRGB_KNEE, linear_to_srgb
from viewer.lighting.lightfit.adam import CosineAdam
from viewer.lighting.lightfit.samples import MapSamples
from viewer.lighting.lightfit.settings import report
from viewer.lighting.lightfit.sphere_lobes import ROTATIONS, SphereLobes, SphereView, rotation_matrices, sphere_reference, sphere_view
from viewer.lighting.median_cut import LUMINANCE


def srgb_slope(x: np.ndarray) -> np.ndarray:
    """d linear_to_srgb / dx (0 below 0, as the twin's clamp)."""
    power = (1.055 / 2.4) * np.maximum(x, SRGB_KNEE) ** (1.0 / 2.4 - 1.0)
    return np.where(x < 0.0, 0.0, np.where(x <= SRGB_KNEE, 12.92, power))


class SphereTarget:
    """The sphere view and the map's normalized diffuse and specular (K, P, 3) on its P pixels, one
    per rotation of the map."""

    def __init__(self, view: SphereView, diffuse: np.ndarray, specular: np.ndarray, rotations=ROTATIONS):
        self.view = view
        self.normal = np.asarray(view.normal, dtype=np.float64)
        self.diffuse = np.asarray(diffuse, dtype=np.float64)
        self.specular = np.asarray(specular, dtype=np.float64)
        self.lobes = SphereLobes(self.normal)
        self.matrices = np.stack(rotation_matrices(rotations))  # (K, 3, 3)
        self.encoded = (linear_to_srgb(self.diffuse), linear_to_srgb(self.specular))

    def loss_and_gradient(self, direction: np.ndarray, intensity: np.ndarray):
        """The loss of unit ``direction`` (N, 3) and ``intensity`` (N, 3), and its gradients with respect to both."""
        mats = self.matrices
        k, n = len(mats), len(direction)
        turned = (direction @ mats.transpose(0, 2, 1)).reshape(k * n, 3)  # R_k l for every rotation and light
        diff, spec, ds_dc, ds_dlz = (a.reshape(k, n, -1) for a in self.lobes.shading_and_slopes(turned))
        count = self.diffuse.size
        loss = 0.0
        grad_intensity = np.zeros_like(intensity)
        grad_turned = np.zeros((k, n, 3))
        for lobe, reference, slope_c in ((diff, self.encoded[0], None), (spec, self.encoded[1], ds_dc)):
            image = np.matmul(lobe.transpose(0, 2, 1), intensity)  # (K, P, 3)
            error = linear_to_srgb(image) - reference
            loss += float(np.abs(error).sum()) / count
            g_image = np.sign(error) * srgb_slope(image) / count
            grad_intensity += np.matmul(lobe, g_image).sum(axis=0)
            g_lobe = np.matmul(intensity, g_image.transpose(0, 2, 1))  # (K, N, P)
            if slope_c is None:  # Lambert: d/dc = [c > 0] / pi, and the lobe is c / pi where positive
                grad_turned += (g_lobe * (lobe > 0.0) / np.pi) @ self.normal
            else:
                grad_turned += (g_lobe * slope_c) @ self.normal
                grad_turned[..., 2] += (g_lobe * ds_dlz).sum(axis=2)
        grad_direction = (grad_turned @ mats).sum(axis=0)  # sum_k R_k^T g_k
        return loss, grad_direction, grad_intensity


def sphere_target(samples: MapSamples, resolution: int, rotations=ROTATIONS) -> tuple[SphereTarget, float]:
    """The sphere view's reference under the map's ``samples``, normalized so that its mean diffuse
    luminance is 1 (a 1e6 sun and a dim night map fitted in one numeric range), and that scale
    (0 for a black map)."""
    view = sphere_view(resolution)
    diff, spec = sphere_reference(samples, view.normal, rotations)
    scale = float((diff @ LUMINANCE).mean())
    inv = 1.0 / scale if scale > 0 else 0.0
    return SphereTarget(view, diff * inv, spec * inv, rotations), scale


def refine(target: SphereTarget, direction: np.ndarray, intensity: np.ndarray, steps: int, lr: float,
           progress=None) -> tuple[np.ndarray, np.ndarray]:
    """``steps`` Adam steps (betas 0.5, 0.999, the learning rate cosine-annealed to 0) on the raw
    directions and the log-intensities from (``direction``, normalized ``intensity``); the last iterate."""
    raw = np.array(direction, dtype=np.float64)
    floor = 1e-6 * float(intensity.sum(axis=1).max())  # lights without energy may grow from a small seed
    log_int = np.log(np.maximum(intensity, floor))
    opt = CosineAdam([raw, log_int], lr=lr, betas=(0.5, 0.999), t_max=steps)
    report(progress, "directions", 0, steps)
    for step in range(steps):
        length = np.maximum(np.linalg.norm(raw, axis=1, keepdims=True), 1e-12)
        unit = raw / length
        inten = np.exp(log_int)
        _, g_unit, g_int = target.loss_and_gradient(unit, inten)
        g_raw = (g_unit - unit * (unit * g_unit).sum(axis=1, keepdims=True)) / length
        opt.step([g_raw, g_int * inten])
        report(progress, "directions", step + 1, steps)
    unit = raw / np.maximum(np.linalg.norm(raw, axis=1, keepdims=True), 1e-12)
    return unit, np.exp(log_int)
