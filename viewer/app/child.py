"""The window's long work in a child process: ``python -m viewer.app.child`` reads requests from
standard input, one JSON object a line, and serves them one at a time until its input ends:
``{"what": "photo", "photo": PATH, "max_size": N, "device": D}`` writes (or finds in the cache) the
photo's scene bundle; ``{"what": "lights", "map": PATH, "n": N, "method": M}`` fits (or finds in the
cache) a map's lights. Each request is answered on standard output, one JSON object a line:
``{"stage": NAME}`` (a photo: as each stage of :data:`viewer.photo.inference.STAGES` ends) or ``{"stage":
NAME, "done": D, "total": T}`` (a fit), then ``{"bundle": PATH, "cached": BOOL}`` or ``{"lights": N x
7 array, "cached": BOOL}``, or ``{"error": LINE}``.

Why a process and not a thread: importing torch (its libraries load with the GIL held for ~0.2 s),
the inference's long Python steps and its own GL context (which cannot be made on another thread next
to the window's, ../shared/docs/STACK.md) would each stall the window's frames; in a process, niced,
the window keeps one core and the GIL to itself, and closing the window ends the work at once. It
lives on between requests (:class:`viewer.app.jobs.ChildWorker`), so torch is imported once, as it
starts (the window starts the fitter's when its file browser opens, before a map is chosen).
"""

from __future__ import annotations

import json
import os
import sys


def _say(**fields):
    print(json.dumps(fields), flush=True)


def _photo(req: dict):
    from viewer.photo.inference import cached_bundle

    bundle, cached = cached_bundle(req["photo"], None, max_size=int(req["max_size"]), device=req.get("device", "cpu"),
                                   progress=lambda stage: _say(stage=stage))
    _say(bundle=str(bundle), cached=cached)


def _lights(req: dict):
    from viewer.lighting.envmap import load_envmap
    from viewer.lighting.lightfit import lights_for_map

    lights, cached = lights_for_map(load_envmap(req["map"]), int(req["n"]), req["method"],
                                    progress=lambda stage, done, total: _say(stage=stage, done=done, total=total))
    _say(lights=lights.to_array().tolist(), cached=cached)


SERVES = {"photo": _photo, "lights": _lights}  # what a request asks for -> its work
SOURCE = {"photo": "photo", "lights": "map"}  # the file an error names


def serve(lines) -> None:
    from viewer.cores import WINDOW_CORES, size_pools, work_threads
    from viewer.errors import InputError

    for line in lines:
        try:
            req = json.loads(line)
            work = SERVES[req["what"]]
        except (json.JSONDecodeError, KeyError, TypeError) as exc:
            _say(error=f"not a request the worker serves ({exc}): {line.strip()[:200]}")
            continue
        size_pools(work_threads(reserve=WINDOW_CORES))  # the window's frames keep their core (viewer/cores.py)
        try:
            work(req)
        except InputError as exc:
            _say(error=str(exc))
        except Exception as exc:  # one line for the window's status box, not a traceback
            _say(error=f"{req.get(SOURCE[req['what']])}: {type(exc).__name__}: {exc}")


def main() -> int:
    from viewer.cores import WINDOW_CORES, work_threads

    if hasattr(os, "nice"):
        os.nice(10)  # the window's frames first
    # its GL context's threads (read once, when the first photo's is made) follow its share of the
    # cores as its other pools do, not the window's LP_NUM_THREADS, which it inherited
    os.environ["LP_NUM_THREADS"] = str(work_threads(reserve=WINDOW_CORES))
    import torch  # noqa: F401  (both kinds of work need it: loaded before the first request, not on it)

    serve(sys.stdin)
    return 0


if __name__ == "__main__":
    sys.exit(main())
