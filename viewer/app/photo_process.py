"""A photo's inference in its own process, for the window: ``python -m viewer.app.photo_process
PHOTO`` writes (or finds in the cache) the photo's scene bundle and reports on standard output, one
JSON object a line: ``{"stage": NAME}`` as each stage of :data:`viewer.inference.STAGES` ends, then
``{"bundle": PATH, "cached": BOOL}``, or ``{"error": LINE}`` (exit status 2).

Why a process and not a thread: the inference holds the GIL in long Python steps and needs a GL
context of its own, which cannot be made on another thread next to the window's
(../shared/docs/STACK.md); in a process, niced, the window's frames keep one core and the GIL to
themselves, and closing the window ends the work at once.
"""

from __future__ import annotations

import argparse
import json
import os
import sys


def _say(**fields):
    print(json.dumps(fields), flush=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m viewer.app.photo_process")
    p.add_argument("photo")
    p.add_argument("--mask")
    p.add_argument("--max-size", type=int, required=True)
    p.add_argument("--device", default="cpu")
    args = p.parse_args(argv)
    if hasattr(os, "nice"):
        os.nice(10)  # the window's frames first
    from ..errors import InputError
    from ..inference import cached_bundle

    try:
        bundle, cached = cached_bundle(args.photo, args.mask, max_size=args.max_size, device=args.device,
                                       progress=lambda stage: _say(stage=stage))
    except InputError as exc:
        _say(error=str(exc))
        return 2
    except Exception as exc:  # one line for the window's status box, not a traceback
        _say(error=f"{args.photo}: {type(exc).__name__}: {exc}")
        return 2
    _say(bundle=str(bundle), cached=cached)
    return 0


if __name__ == "__main__":
    sys.exit(main())
