"""Make a bundled demo environment: a small copy of an HDR map and its fitted area lights.

``bundle_envmap(source, out_dir, width, n_lights, method)`` loads ``source`` (.hdr or .exr), area-averages it
to ``width`` x ``width / 2`` with the energy-preserving :meth:`viewer.lighting.envmap.EnvMap.downsampled`,
writes it as ``<name>_<width>.hdr`` (``<name>`` is the source's stem without a resolution suffix such
as ``_1k``), reads that file back and writes its ``n_lights`` lights fitted by ``method`` (the
default method unless given; the bundled maps use ``fast``, :func:`viewer.lighting.lightfit.fit.fit_lights`) as
``<name>_<width>.lights.json``, so the demo shows fitted lights without fitting (and without importing torch).

Run from the project root (positional arguments, no options)::

    .venv/bin/python -m tools.bundle_envmap SOURCE OUT_DIR WIDTH N_LIGHTS [METHOD]
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

from viewer.lighting.envmap import load_envmap, save_envmap
from viewer.lighting.lightfit import DEFAULT_METHOD
from viewer.lighting.lightfit.cache import fit_record
from viewer.lighting.lightfit.fit import fit_lights


def bundle_envmap(source, out_dir, width: int, n_lights: int, method: str = DEFAULT_METHOD) -> tuple[Path, Path]:
    """Write the downsampled map and its lights into ``out_dir``; return both paths."""
    source, out_dir = Path(source), Path(out_dir)
    name = re.sub(r"_\d+k$", "", source.stem) + f"_{width}"
    hdr = save_envmap(out_dir / f"{name}.hdr", load_envmap(source).downsampled(width))
    env = load_envmap(hdr)
    fitted = fit_lights(env, n_lights, method)
    lights = out_dir / f"{name}.lights.json"
    fitted.save(lights, fit=fit_record(hdr, method, n_lights, env))
    return hdr, lights


if __name__ == "__main__":
    src, out, w, n, *method = sys.argv[1:]
    for written in bundle_envmap(src, out, int(w), int(n), *method):
        print(written)
