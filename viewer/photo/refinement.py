"""The engine's 'refined' shadow mode: the shadow refinement network (:mod:`viewer.nets.refine`)
applied to the hard and convolutional-shadow-map visibility the GL engine computed for the
current lights, its output handed back to the engine (``Engine.set_refined_visibility``).

It runs once per lighting, not per frame (about a second at 512^2 on 2 CPU cores, see
docs/networks.md): the viewer asks for it when the lighting stops moving and shows the soft
visibility until it arrives. torch is imported only here, when the mode is used.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.resources import network_dir

LIGHTS_PER_BATCH = 4


class Refiner:
    """Loads the refinement network once; ``__call__`` gives the refined visibility (N, H, W)."""

    def __init__(self, path=None, device: str = "cpu"):
        from viewer.nets.weights import load_network

        self.path = Path(path) if path is not None else network_dir() / "refine.safetensors"
        if not self.path.is_file():
            raise InputError(self.path, "the shadow refinement network is not installed (assets/networks/refine.safetensors)")
        self.device = device
        self.model = load_network(self.path, device)

    def __call__(self, hard: np.ndarray, soft: np.ndarray, sigma: np.ndarray, depth: np.ndarray,
                 mask: np.ndarray, cancelled=None) -> np.ndarray:
        """hard, soft (N, H, W); sigma (N,); depth, mask (H, W) -> refined visibility (N, H, W).
        ``cancelled()``, if given, is called before each batch of lights (it raises to stop)."""
        import torch

        from viewer.nets.refine import refined_visibility

        n = hard.shape[0]
        multiple = self.model.multiple
        h, w = mask.shape
        ph, pw = -h % multiple, -w % multiple  # pad to the U-Net's multiple

        def t(a):
            x = torch.as_tensor(np.ascontiguousarray(a, np.float32), device=self.device)
            return torch.nn.functional.pad(x, (0, pw, 0, ph))

        d, m = t(depth)[None, None], t(mask.astype(np.float32))[None, None]
        out = np.zeros((n, h, w), np.float32)
        with torch.no_grad():
            for start in range(0, n, LIGHTS_PER_BATCH):
                if cancelled is not None:
                    cancelled()
                sl = slice(start, min(start + LIGHTS_PER_BATCH, n))
                v = refined_visibility(self.model, t(hard[sl])[None], t(soft[sl])[None],
                                       torch.as_tensor(sigma[sl], dtype=torch.float32, device=self.device)[None], d, m)
                out[sl] = v[0, :, :h, :w].cpu().numpy()
        return out * mask


def light_visibility(engine) -> tuple[np.ndarray, np.ndarray]:
    """(hard, soft) visibility (N, H, W) of the engine's current lights (rendered first)."""
    engine.render()
    data = [engine.output.read_light(i) for i in range(len(engine.lights))]
    return (np.stack([d["visibility_hard"] for d in data]), np.stack([d["visibility_soft"] for d in data]))


def refine_engine(engine, refiner: Refiner) -> np.ndarray:
    """Compute and set the refined visibility of the engine's current lights; returns it."""
    hard, soft = light_visibility(engine)
    scene = engine.scene
    vis = refiner(hard, soft, engine.lights.sigma, scene.depth, scene.mask)
    engine.set_refined_visibility(vis)
    return vis
