"""A picture of area lights drawn on their environment map (the paper's figure of fitted lights).

The map is shown tone-mapped (exposure set so its 99th luminance percentile is white, sRGB); each
light is a circle at its direction's pixel, its size growing with sigma (sharp lights are small
dots), filled with a colour from the light's luminance on a log scale (colour bar), and numbered.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from viewer.files.imageio import MARK, atomic_path, linear_to_srgb
from viewer.lighting.envmap import EnvMap, direction_to_uv
from viewer.lighting.median_cut import LUMINANCE
from viewer.scene.area_lights import AreaLights


def display_map(env: EnvMap) -> np.ndarray:
    """(H, W, 3) sRGB image of the map in [0, 1]."""
    lum = env.pixels @ LUMINANCE.astype(np.float32)
    white = float(np.percentile(lum, 99)) if lum.size else 0.0
    scaled = env.pixels / white if white > 0 else env.pixels
    return linear_to_srgb(np.clip(scaled, 0.0, 1.0))


def plot_lights(env: EnvMap, lights: AreaLights, path, title: str | None = None) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    h, w = env.height, env.width
    uv = direction_to_uv(lights.direction) * np.array([w, h])
    lum = np.maximum(lights.intensity.astype(np.float64) @ LUMINANCE, 0.0)
    positive = lum[lum > 0]
    fig, ax = plt.subplots(figsize=(10, 5.6), dpi=110)
    ax.imshow(display_map(env), extent=(0, w, h, 0), interpolation="bilinear")
    if len(positive):
        norm = LogNorm(vmin=max(positive.min(), positive.max() * 1e-4), vmax=positive.max() * (1 + 1e-9))
        colours = np.maximum(lum, norm.vmin)
        dots = ax.scatter(uv[:, 0], uv[:, 1], s=30 + 40 * lights.sigma, c=colours, cmap="plasma", norm=norm,
                          edgecolors="white", linewidths=1.2, zorder=3)
        fig.colorbar(dots, ax=ax, fraction=0.025, pad=0.01, label="light luminance (intensity)")
    else:
        ax.scatter(uv[:, 0], uv[:, 1], s=30 + 40 * lights.sigma, facecolors="none", edgecolors="white", zorder=3)
    for i, (x, y) in enumerate(uv):
        ax.annotate(str(i), (x, y), xytext=(5, 5), textcoords="offset points", color="white", fontsize=8,
                    zorder=4)
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)
    ax.set_xticks(np.linspace(0, w, 5), ["-180", "-90", "0", "90", "180"])
    ax.set_yticks(np.linspace(0, h, 5), ["90", "45", "0", "-45", "-90"])
    ax.set_xlabel("longitude (degrees; 0 = -z, behind the subject)")
    ax.set_ylabel("latitude (degrees)")
    name = Path(env.source).name if env.source else "environment map"
    ax.set_title(title or f"{len(lights)} area lights on {name} (marker size: sigma {lights.sigma.min():.1f}-{lights.sigma.max():.1f})")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", metadata={MARK[0]: MARK[1]})  # a PNG text chunk: viewer.files.ownership
    plt.close(fig)
    return path
