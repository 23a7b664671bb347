"""Convolutional shadow maps (Annen et al. 2007, the paper's soft shadows) and the hard shadow test.

Torch twin of ``shaders/csm*.glsl``, ``shaders/gaussian_blur.frag.glsl`` and
``shaders/shadow_test.glsl``, batched over lights (leading dimension N) and differentiable with
respect to each light's sigma.

- Fourier basis of a shadow map z: 2M maps, channel 2k = cos(c_k z), channel 2k + 1 = sin(c_k z),
  c_k = pi (2k + 1) for k = 0 .. M - 1 (the GL engine packs the same order into RGBA textures).
- Pre-filtering: a separable Gaussian of sigma_px = sigma R / 256 texels (the area light's sigma,
  :func:`viewer.scene.shadow_space.sigma_in_pixels`), discrete weights exp(-t^2 / (2 sigma_px^2)) for
  |t| <= ceil(3 sigma_px) (kernel size 2 ceil(3 sigma_px) + 1, as the paper), normalised to sum 1.
  Borders are clamp-to-edge (replicate padding), like the GL engine's texel fetches. sigma_px below
  1e-3 is the identity filter (its gradient is then zero).
- Soft visibility: the filtered basis is sampled bilinearly at the receiver's (u, v) (texel centres
  at (j + 0.5) / R, clamp-to-edge), S = sum_k (2 / c_k) [cos(c_k d') F[sin c_k z] - sin(c_k d')
  F[cos c_k z]] with d' = clamp(d, 0, 1) - offset (so a receiver pushed past the range never wraps), and
  V = clamp((S + a) / 2a, 0, 1); (offset, a) from
  :func:`viewer.scene.shadow_space.csm_constants`.
- Hard visibility: the texel containing (u, v) (floor, clamp-to-edge); lit when d - bias <= z.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from viewer.scene import shadow_space as rule

MIN_SIGMA_PX = 1e-3  # below this many texels the pre-filter is the identity


def fourier_basis(depth: torch.Tensor, terms: int = 4) -> torch.Tensor:
    """CSM basis maps (N, 2M, R, R) of shadow maps ``depth`` (N, R, R): cos/sin(c_k z) interleaved."""
    c = torch.as_tensor(rule.csm_frequencies(terms), dtype=depth.dtype, device=depth.device)
    phase = c[None, :, None, None] * depth[:, None]  # (N, M, R, R)
    return torch.stack([torch.cos(phase), torch.sin(phase)], dim=2).flatten(1, 2)


def gaussian_kernels(sigma_px: torch.Tensor) -> torch.Tensor:
    """Normalised 1-D Gaussian kernels (N, 2 r_max + 1), each truncated at its own ceil(3 sigma_px).

    Built from the sigma tensor with torch ops, so gradients flow to sigma; lights with sigma_px
    below MIN_SIGMA_PX get the unit impulse.
    """
    radius = torch.where(sigma_px.detach() < MIN_SIGMA_PX, torch.zeros_like(sigma_px),
                         torch.ceil(3.0 * sigma_px.detach()))  # (N,)
    r_max = int(radius.max().item()) if radius.numel() else 0
    t = torch.arange(-r_max, r_max + 1, dtype=sigma_px.dtype, device=sigma_px.device)
    s = sigma_px.clamp(min=MIN_SIGMA_PX)[:, None]
    w = torch.exp(-0.5 * (t[None] / s) ** 2) * (t[None].abs() <= radius[:, None])
    return w / w.sum(dim=1, keepdim=True)


def _fft_size(n: int) -> int:
    """Smallest 2^a 3^b 5^c >= n: a length the FFT handles fast."""
    best = 1 << max(n - 1, 0).bit_length()
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            m = p35
            while m < n:
                m *= 2
            best = min(best, m)
            p35 *= 3
        p5 *= 5
    return best


def _convolve_axis(x: torch.Tensor, kernels: torch.Tensor, dim: int) -> torch.Tensor:
    """Convolve (N, C, R, R) along ``dim`` with symmetric kernels (N, 2r + 1), replicate borders.

    The zero-padded convolution is done by FFT (its cost does not grow with the kernel width; the
    transform is long enough that nothing wraps around), then the taps that fall off either end
    are given the edge values: output i gains x[0] sum_{t > i} k[t] and x[B-1] sum_{t < i-B+1} k[t].
    """
    n, r = kernels.shape[0], (kernels.shape[1] - 1) // 2
    b = x.shape[dim]
    length = _fft_size(max(b + r, 2 * r + 1))
    gap = torch.zeros(n, length - 2 * r - 1, dtype=kernels.dtype, device=kernels.device)
    circular = torch.cat([kernels[:, r:], gap, kernels[:, :r]], dim=1)  # offsets 0..r, then -r..-1
    shape = [n, 1, 1, 1]
    shape[dim] = -1
    spectrum = torch.fft.rfft(x, n=length, dim=dim) * torch.fft.rfft(circular, dim=1).reshape(shape)
    out = torch.fft.irfft(spectrum, n=length, dim=dim).narrow(dim, 0, b)
    cum = torch.cumsum(kernels, dim=1)  # cum[j] = sum of the taps at offsets <= j - r
    k = min(r, b)  # only the first and last r outputs have taps beyond the ends
    head = torch.arange(k, device=x.device)
    tail = torch.arange(b - k, b, device=x.device)
    left = 1.0 - cum[:, head + r]  # taps reaching before index 0
    right = cum[:, (tail - b + r).clamp(min=0)] * (tail - b + r >= 0)  # taps reaching past index b - 1
    out.narrow(dim, 0, k).add_(x.narrow(dim, 0, 1) * left.reshape(shape))
    out.narrow(dim, b - k, k).add_(x.narrow(dim, b - 1, 1) * right.reshape(shape))
    return out


def gaussian_filter(maps: torch.Tensor, sigma_px: torch.Tensor) -> torch.Tensor:
    """Separable Gaussian pre-filter of per-light maps (N, C, R, R), sigma in texels (N,), replicate borders."""
    kernels = gaussian_kernels(sigma_px.to(maps.dtype))
    if kernels.shape[1] == 1:
        return maps
    return _convolve_axis(_convolve_axis(maps, kernels, -1), kernels, -2)


def sample_bilinear(maps: torch.Tensor, u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Bilinear samples (N, C, P) of maps (N, C, R, R) at (u, v) (N, P) in [0, 1], clamp-to-edge.

    Texel (i, j) has its centre at ((j + 0.5) / R, (i + 0.5) / R); row 0 is at v = 0.
    """
    grid = torch.stack([2.0 * u - 1.0, 2.0 * v - 1.0], dim=-1)[:, None].to(maps.dtype)  # (N, 1, P, 2)
    out = F.grid_sample(maps, grid, mode="bilinear", padding_mode="border", align_corners=False)
    return out[:, :, 0]


def reconstruct_visibility(basis: torch.Tensor, d: torch.Tensor, terms: int = 4) -> torch.Tensor:
    """Soft visibility (N, P) from filtered basis values (N, 2M, P) at receivers of depth d (N, P)."""
    offset, clamp = rule.csm_constants(terms)
    c = torch.as_tensor(rule.csm_frequencies(terms), dtype=d.dtype, device=d.device)[None, :, None]
    phase = c * (d.clamp(0.0, 1.0) - offset)[:, None]  # (N, M, P); clamped so nothing wraps
    f_cos, f_sin = basis[:, 0::2], basis[:, 1::2]
    s = ((2.0 / c) * (torch.cos(phase) * f_sin - torch.sin(phase) * f_cos)).sum(dim=1)
    return ((s + clamp) / (2.0 * clamp)).clamp(0.0, 1.0)


def soft_visibility(depth: torch.Tensor, sigma: torch.Tensor, u: torch.Tensor, v: torch.Tensor,
                    d: torch.Tensor, terms: int = 4) -> torch.Tensor:
    """Convolutional-shadow-map visibility (N, P) of receivers (u, v, d) (N, P) in shadow maps (N, R, R).

    ``sigma`` (N,) is the area lights' sigma in 256-pixel units, converted to texels of these maps.
    """
    res = depth.shape[-1]
    sigma_px = sigma.to(depth.dtype) * (res / rule.SIGMA_REFERENCE_RESOLUTION)
    filtered = gaussian_filter(fourier_basis(depth, terms), sigma_px)
    return reconstruct_visibility(sample_bilinear(filtered, u, v), d, terms)


def shadow_depth(depth: torch.Tensor, u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """(N, P): the depth of shadow maps (N, R, R) in the texel containing each (u, v) (clamped to
    the map), as shaders/shadow_test.glsl's ``shadow_depth``."""
    n, res = depth.shape[0], depth.shape[-1]
    j = torch.floor(u * res).clamp(0, res - 1).long()
    i = torch.floor(v * res).clamp(0, res - 1).long()
    return depth.reshape(n, -1).gather(1, i * res + j)


def hard_visibility(depth: torch.Tensor, u: torch.Tensor, v: torch.Tensor, d: torch.Tensor,
                    bias: torch.Tensor) -> torch.Tensor:
    """Hard shadow-map visibility (N, P), 1 lit / 0 shadowed: the texel containing (u, v) (clamped
    to the map) is compared with the receiver, lit when d - bias <= z."""
    return (d - bias <= shadow_depth(depth, u, v)).to(depth.dtype)


def twin_visibility(depth, sigma, frames, u, v, d, bias, normal, terms: int):
    """:func:`soft_visibility` with the arguments every soft-shadow method's twin takes
    (:meth:`viewer.gl.soft.SoftMethod.twin`)."""
    return soft_visibility(depth, sigma, u, v, d, terms)
