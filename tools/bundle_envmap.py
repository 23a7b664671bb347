"""Make a bundled demo environment: a small copy of an HDR map and its median-cut lights.

``bundle_envmap(source, out_dir, width, n_lights)`` loads ``source`` (.hdr or .exr), area-averages it
to ``width`` x ``width / 2`` with the energy-preserving :meth:`viewer.envmap.EnvMap.downsampled`,
writes it as ``<name>_<width>.hdr`` (``<name>`` is the source's stem without a resolution suffix such
as ``_1k``), reads that file back and writes its ``n_lights`` median-cut lights
(:func:`viewer.median_cut.median_cut_lights`) as ``<name>_<width>.lights.json``. The lights are made
from the written file, so ``median_cut_lights(load_envmap(hdr), n_lights)`` reproduces them.

Run from the project root (positional arguments, no options)::

    .venv/bin/python -m tools.bundle_envmap SOURCE OUT_DIR WIDTH N_LIGHTS
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

from viewer.envmap import load_envmap, save_envmap
from viewer.median_cut import median_cut_lights


def bundle_envmap(source, out_dir, width: int, n_lights: int) -> tuple[Path, Path]:
    """Write the downsampled map and its lights into ``out_dir``; return both paths."""
    source, out_dir = Path(source), Path(out_dir)
    name = re.sub(r"_\d+k$", "", source.stem) + f"_{width}"
    hdr = save_envmap(out_dir / f"{name}.hdr", load_envmap(source).downsampled(width))
    lights = median_cut_lights(load_envmap(hdr), n_lights).save(out_dir / f"{name}.lights.json")
    return hdr, lights


if __name__ == "__main__":
    src, out, w, n = sys.argv[1:]
    for written in bundle_envmap(src, out, int(w), int(n)):
        print(written)
