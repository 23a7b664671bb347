"""Adam with a cosine-annealed learning rate (torch.optim.Adam + CosineAnnealingLR, closed form), on numpy arrays.

Why not torch.optim: its optimizers import ``torch._dynamo`` (and sympy) on first use (0.9 s of a
cold fit on this machine), and the default fits run without torch at all (:mod:`.sphere_fit`).
The paper's method (torch) steps its tensors through their numpy views (``tensor.detach().numpy()``
shares the tensor's memory). The update is torch's default Adam (no weight decay, no amsgrad,
eps 1e-8); ``tests/test_lightfit.py`` checks it against torch.optim step for step.
"""

from __future__ import annotations

import math

import numpy as np


class CosineAdam:
    """``step(grads)`` applies one Adam update to ``params`` (arrays, updated in place) and moves the
    learning rate along ``eta_min + (lr - eta_min) (1 + cos(pi t / t_max)) / 2`` (periodic past ``t_max``)."""

    def __init__(self, params, lr: float, betas=(0.9, 0.999), t_max: int = 1, eta_min: float = 0.0, eps: float = 1e-8):
        self.params = list(params)
        self.base_lr, self.betas, self.t_max, self.eta_min, self.eps = lr, betas, t_max, eta_min, eps
        self.m = [np.zeros_like(p) for p in self.params]
        self.v = [np.zeros_like(p) for p in self.params]
        self.t = 0

    @property
    def lr(self) -> float:
        return self.eta_min + (self.base_lr - self.eta_min) * (1 + math.cos(math.pi * self.t / self.t_max)) / 2

    def step(self, grads):
        """One update from ``grads``, one per parameter (None: that parameter stays)."""
        b1, b2 = self.betas
        lr = self.lr
        self.t += 1
        for p, m, v, g in zip(self.params, self.m, self.v, grads):
            if g is None:
                continue
            m *= b1
            m += (1 - b1) * g
            v *= b2
            v += (1 - b2) * g * g
            denom = np.sqrt(v) / math.sqrt(1 - b2**self.t) + self.eps
            p -= (lr / (1 - b1**self.t)) * m / denom
