"""Make a before / now figure of ``relight bench colour``'s contact sheets: for each photo, the photo's
row, then each look's row from an earlier product's run and from this one's, one above the other, at
100 % (the crops of the face, the hair and the clothes as the bench cut them).

Run from the project root, after ``relight bench colour`` ran in the earlier product's checkout
(``-o BEFORE``) and in this one (``-o NOW``)::

    .venv/bin/python -m tools.colour_figure OUT.jpg BEFORE NOW STEM [STEM ...]

docs/photos.md shows its figure for the two shared photos (whose terms allow it).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from viewer.lab.bench.photo_set import SHEET_CELL as CELL, SHEET_LABEL as LABEL

LOOKS = ("white", "studio", "key")  # the sheet's rows after the photo's


def rows(sheet: np.ndarray) -> dict:
    """label -> the row's crops (without the label column) of a contact sheet."""
    out = {}
    for k, label in enumerate(("photo",) + LOOKS):
        out[label] = sheet[k * CELL:(k + 1) * CELL, LABEL:]
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("output")
    p.add_argument("before", type=Path, help="the earlier product's bench colour output folder")
    p.add_argument("now", type=Path, help="this product's bench colour output folder")
    p.add_argument("stems", nargs="+", help="the photos' file names without their suffix")
    args = p.parse_args(argv)
    from PIL import Image, ImageDraw

    from viewer.files.imageio import write_jpeg

    blocks = []
    for stem in args.stems:
        before = rows(np.asarray(Image.open(args.before / f"colour_{stem}.jpg").convert("RGB")))
        now = rows(np.asarray(Image.open(args.now / f"colour_{stem}.jpg").convert("RGB")))
        labelled = [("photo", now["photo"])] + [(f"{look}, {when}", r[look]) for look in LOOKS
                                                 for when, r in (("before", before), ("now", now))]
        width = max(image.shape[1] for _, image in labelled)
        block = Image.new("RGB", (width + 150, CELL * len(labelled)), (128, 128, 128))
        draw = ImageDraw.Draw(block)
        for k, (label, image) in enumerate(labelled):
            block.paste(Image.fromarray(np.ascontiguousarray(image)), (150, k * CELL))
            draw.text((6, k * CELL + 6), label, fill=(255, 255, 255))
        blocks.append(np.asarray(block))
    height = sum(b.shape[0] for b in blocks)
    figure = np.full((height, max(b.shape[1] for b in blocks), 3), 128, np.uint8)
    y = 0
    for b in blocks:
        figure[y:y + b.shape[0], :b.shape[1]] = b
        y += b.shape[0]
    write_jpeg(args.output, figure.astype(np.float32) / 255.0, quality=85)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
