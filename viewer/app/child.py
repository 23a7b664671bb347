"""The window's long work in a child process: ``python -m viewer.app.child photo PHOTO --max-size N``
writes (or finds in the cache) the photo's scene bundle; ``python -m viewer.app.child lights MAP -n N
--method M`` fits (or finds in the cache) a map's lights. Each reports on standard output, one JSON
object a line: ``{"stage": NAME}`` (a photo: as each stage of :data:`viewer.inference.STAGES` ends)
or ``{"stage": NAME, "done": D, "total": T}`` (a fit), then ``{"bundle": PATH, "cached": BOOL}`` or
``{"lights": N x 7 array, "cached": BOOL}``, or ``{"error": LINE}`` (exit status 2).

Why a process and not a thread: importing torch (its libraries load with the GIL held for ~0.2 s),
the inference's long Python steps and its own GL context (which cannot be made on another thread next
to the window's, ../shared/docs/STACK.md) would each stall the window's frames; in a process, niced,
the window keeps one core and the GIL to itself, and closing the window ends the work at once.
"""

from __future__ import annotations

import argparse
import json
import os
import sys


def _say(**fields):
    print(json.dumps(fields), flush=True)


def _photo(args):
    from ..inference import cached_bundle

    bundle, cached = cached_bundle(args.photo, None, max_size=args.max_size, device=args.device,
                                   progress=lambda stage: _say(stage=stage))
    _say(bundle=str(bundle), cached=cached)


def _lights(args):
    from ..envmap import load_envmap
    from ..lightfit import lights_for_map

    lights, cached = lights_for_map(load_envmap(args.map), args.n, args.method,
                                    progress=lambda stage, done, total: _say(stage=stage, done=done, total=total))
    _say(lights=lights.to_array().tolist(), cached=cached)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m viewer.app.child")
    sub = p.add_subparsers(dest="what", required=True)
    photo = sub.add_parser("photo")
    photo.add_argument("photo")
    photo.add_argument("--max-size", type=int, required=True)
    photo.add_argument("--device", default="cpu")
    photo.set_defaults(func=_photo, source="photo")
    lights = sub.add_parser("lights")
    lights.add_argument("map")
    lights.add_argument("-n", type=int, required=True)
    lights.add_argument("--method", required=True)
    lights.set_defaults(func=_lights, source="map")
    args = p.parse_args(argv)
    if hasattr(os, "nice"):
        os.nice(10)  # the window's frames first
    from ..errors import InputError

    try:
        args.func(args)
    except InputError as exc:
        _say(error=str(exc))
        return 2
    except Exception as exc:  # one line for the window's status box, not a traceback
        _say(error=f"{getattr(args, args.source)}: {type(exc).__name__}: {exc}")
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
