"""``relight plate-light PLATE -o MAP.exr``: the light read from a background photo, as an HDR map
(:mod:`viewer.plate.plate_light`), to inspect, edit and use as any map (``--env MAP.exr``)."""

from __future__ import annotations

import json
import time
from pathlib import Path

from viewer.cli.output_paths import not_an_input, writable
from viewer.errors import InputError
from viewer.files.ownership import refuse_foreign


def cmd_plate_light(args) -> int:
    from viewer.lighting.envmap import save_envmap
    from viewer.plate.plate_file import read_plate
    from viewer.plate.plate_light import plate_light

    out = Path(args.output)
    if out.suffix.lower() != ".exr":
        raise InputError(out, "the plate's light is written as an OpenEXR map: give a .exr output path")
    writable(out)
    not_an_input([out], [args.plate])
    refuse_foreign([out], args.force)
    notes: list = []
    start = time.perf_counter()
    plate = read_plate(args.plate, notes)
    env, record = plate_light(plate, args.height)
    seconds = time.perf_counter() - start
    save_envmap(out, env)
    for note in notes:
        print(f"note: {note}")
    print(f"{out}: the light of {args.plate} ({plate.size[0]}x{plate.size[1]}, {record['focal_35mm']:g} mm from "
          f"{record['focal_from']}, {record['field_of_view_deg']:.0f} degrees across), {env.width}x{env.height}, "
          f"in {seconds:.2f} s")
    if args.record:
        print(json.dumps(record))
    return 0
