"""Adam with a cosine-annealed learning rate: torch.optim.Adam + CosineAnnealingLR (closed form).

Why not torch.optim: its optimizers import ``torch._dynamo`` (and sympy) on first use, 0.9 s of a
cold 2.1 s instant fit on this machine, which a user pays on every ``relight fit-lights`` and on the
viewer's first map. The update is torch's default Adam (no weight decay, no amsgrad, eps 1e-8);
``tests/test_lightfit.py`` checks it against torch.optim step for step.
"""

from __future__ import annotations

import math

import torch


class CosineAdam:
    """``step()`` applies one Adam update to ``params`` from their ``.grad`` and moves the learning
    rate along ``eta_min + (lr - eta_min) (1 + cos(pi t / t_max)) / 2`` (periodic past ``t_max``)."""

    def __init__(self, params, lr: float, betas=(0.9, 0.999), t_max: int = 1, eta_min: float = 0.0, eps: float = 1e-8):
        self.params = list(params)
        self.base_lr, self.betas, self.t_max, self.eta_min, self.eps = lr, betas, t_max, eta_min, eps
        self.m = [torch.zeros_like(p) for p in self.params]
        self.v = [torch.zeros_like(p) for p in self.params]
        self.t = 0

    @property
    def lr(self) -> float:
        return self.eta_min + (self.base_lr - self.eta_min) * (1 + math.cos(math.pi * self.t / self.t_max)) / 2

    def zero_grad(self):
        for p in self.params:
            p.grad = None

    @torch.no_grad()
    def step(self):
        b1, b2 = self.betas
        lr = self.lr
        self.t += 1
        for p, m, v in zip(self.params, self.m, self.v):
            if p.grad is None:
                continue
            m.mul_(b1).add_(p.grad, alpha=1 - b1)
            v.mul_(b2).addcmul_(p.grad, p.grad, value=1 - b2)
            denom = (v.sqrt() / math.sqrt(1 - b2 ** self.t)).add_(self.eps)
            p.addcdiv_(m, denom, value=-lr / (1 - b1 ** self.t))
