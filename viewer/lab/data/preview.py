"""``relight dataset preview``: what the generator makes, as pictures (docs/dataset.md's figures).

- people: ``count`` random people of a seed, each as albedo, camera-space normal and the normal lit
  by one key light from the upper left (so folds, hair and pose read at a glance), with the pose
  style and outfit written under them;
- maps: two procedural maps of every kind, exposed by their 90th percentile.

Everything is drawn from the seed alone, as the dataset is, so the figures can be made again.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

KEY_LIGHT = np.array([-0.5, 0.6, 0.6]) / np.linalg.norm([-0.5, 0.6, 0.6])


def _srgb8(linear: np.ndarray) -> np.ndarray:
    from viewer.files.imageio import linear_to_srgb

    return (np.clip(linear_to_srgb(np.clip(linear, 0.0, 1.0)), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def person_tiles(seed: int, size: int) -> tuple[np.ndarray, str]:
    """(albedo, normal and key-lit tiles side by side, cropped to the person; a caption) of the
    dataset person of ``seed``."""
    from viewer.lab.data.people import make_person

    p = make_person(seed, size)
    s = p.scene
    m = s.mask[..., None]
    normal = np.where(m, (s.normal * 0.5 + 0.5), 0.0)
    lit = np.where(m, np.clip(s.normal @ KEY_LIGHT, 0.0, 1.0)[..., None] * np.ones(3), 0.0)
    rows, cols = np.nonzero(s.mask)
    pad = size // 40
    r0, r1 = max(rows.min() - pad, 0), min(rows.max() + pad + 1, size)
    c0, c1 = max(cols.min() - pad, 0), min(cols.max() + pad + 1, size)  # the person, not the empty frame
    tiles = np.concatenate([img[r0:r1, c0:c1] for img in (_srgb8(s.albedo), (normal * 255 + 0.5).astype(np.uint8), _srgb8(lit))],
                           axis=1)
    o = p.outfit
    a = o.accessories
    worn = [a.bag] if a.bag else []
    worn += [name for name, v in (("watch", a.watch), ("necklace", a.necklace), ("cap", a.cap)) if v is not None]
    caption = f"{p.pose_style.replace('_', ' ')}; {'long' if o.hair_length else 'short'} hair; top: {o.top.pattern}"
    caption += f"; {', '.join(worn)}" if worn else ""
    return tiles, caption


def map_tile(seed: int, kind: str, width: int) -> np.ndarray:
    from viewer.lab.data.envmaps import random_map

    px = random_map(seed, width, kinds=(kind,)).env.pixels
    return _srgb8(px * 0.7 / max(float(np.percentile(px.mean(axis=-1), 90)), 1e-12))


def preview(out_dir: Path, seed: int = 0, count: int = 8, size: int = 256) -> list[Path]:
    """Write ``dataset_people.png`` and ``procedural_envmaps.png`` into ``out_dir``; returns them."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from viewer.lab.data.envmaps import KINDS

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    cols = min(count, 4)
    rows = -(-count // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.4 * cols, 4.2 * rows), dpi=110, squeeze=False)
    for ax in axes.flat:
        ax.axis("off")
    for ax, k in zip(axes.flat, range(count)):
        tiles, caption = person_tiles(seed * 1_000_003 + k, size)
        ax.imshow(tiles)
        ax.set_title(caption, fontsize=8)
    fig.suptitle("random people (albedo, normal, normal under a key light)", fontsize=9)
    written.append(_save(fig, out_dir / "dataset_people.png"))

    fig, axes = plt.subplots(len(KINDS), 2, figsize=(7.0, 1.9 * len(KINDS)), dpi=110)
    for row, kind in enumerate(KINDS):
        for col in range(2):
            ax = axes[row, col]
            ax.imshow(map_tile(seed * 1000 + 17 * row + col, kind, 256))
            ax.set_title(kind if col == 0 else "", fontsize=8, loc="left")
            ax.axis("off")
    written.append(_save(fig, out_dir / "procedural_envmaps.png"))
    return written


def _save(fig, path: Path) -> Path:
    """Lay out ``fig``, write it as a PNG at ``path`` (atomically) and close it."""
    import matplotlib.pyplot as plt

    from viewer.files.imageio import atomic_path

    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return path
