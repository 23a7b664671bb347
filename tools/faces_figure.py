"""Make a before / after figure of faces at 100 %: each pair of scene bundles of one photo (one
inferred by an earlier product, one by this one) rendered by this engine under the same looks, the
crop around the face found on the photo (twice its box).

The looks are those of ``relight bench photos --set`` (viewer/lab/bench/photo_set.py): the studio
map at its automatic yaw, butterfly light (one light from the front and above, a dim fill) and the
key rig (a key from 60 degrees). Run from the project root::

    .venv/bin/python -m tools.faces_figure OUT.jpg --maps DIR BEFORE_BUNDLE:AFTER_BUNDLE [...]

docs/photos.md shows its figure for the two shared photos (whose terms allow it).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def face_box(scene) -> tuple[int, int, int]:
    """(top, left, side) of twice the face's box on the bundle's frame photo."""
    from viewer.lab.bench.photo_set import _srgb8
    from viewer.photo.face import find_faces

    photo = _srgb8(scene.frame.photo)
    h, w = photo.shape[:2]
    faces = find_faces(photo, scene.frame.alpha)
    if not faces:
        raise SystemExit("no face found on the photo")
    x, y, bw, bh = faces[0].box
    side = int(2 * max(bw, bh))
    return (int(np.clip(y + bh / 2 - side / 2, 0, h - side)), int(np.clip(x + bw / 2 - side / 2, 0, w - side)), side)


def looks(maps: Path) -> dict:
    """label -> (lights, environment or None, yaw)."""
    from viewer.lab.bench.photo_set import FRONT_FILL, MAPS, RIGS
    from viewer.lighting.envmap import load_envmap
    from viewer.lighting.lightfit import lights_for_map
    from viewer.scene.area_lights import facing_yaw

    env = load_envmap(maps / f"{MAPS['studio']}.hdr")
    studio = lights_for_map(env)[0]
    return {"studio map": (studio, env.pixels, facing_yaw(studio)), "butterfly + fill": (FRONT_FILL, None, 0.0),
            "key from 60 degrees": (RIGS["key 60"], None, 0.0)}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("output")
    p.add_argument("--maps", required=True, help="folder of the shared .hdr maps")
    p.add_argument("pairs", nargs="+", help="BEFORE_BUNDLE:AFTER_BUNDLE")
    args = p.parse_args(argv)
    from PIL import Image, ImageDraw

    from viewer.files.imageio import write_jpeg
    from viewer.gl import Engine, EngineOptions, create_headless_context
    from viewer.lab.bench.photo_set import _render
    from viewer.scene.bundle import load_scene

    ctx = create_headless_context()
    chosen = looks(Path(args.maps))
    cell = 320
    rows = []
    for pair in args.pairs:
        before, after = pair.split(":")
        scenes = [load_scene(before), load_scene(after)]
        top, left, side = face_box(scenes[1])
        row = []
        for label, (lights, env, yaw) in chosen.items():
            for name, scene in zip(("before", "now"), scenes):
                eng = Engine(ctx, scene, EngineOptions())
                _, display = _render(eng, scene, lights, env, yaw, background="color")
                eng.release()
                tile = Image.fromarray(np.ascontiguousarray(display[top:top + side, left:left + side]))
                tile = tile.resize((cell, cell), Image.LANCZOS if side > cell else Image.NEAREST)
                ImageDraw.Draw(tile).text((4, 4), f"{label}: {name}", fill=(255, 255, 0))
                row.append(tile)
        rows.append(row)
    sheet = Image.new("RGB", (cell * len(rows[0]), cell * len(rows)))
    for r, row in enumerate(rows):
        for c, tile in enumerate(row):
            sheet.paste(tile, (c * cell, r * cell))
    write_jpeg(Path(args.output), np.asarray(sheet).astype(np.float32) / 255.0, quality=90)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
