"""A batch's contact sheet: a row per photo (the photo, then each of its looks as the batch rendered
it), the look's name over each column; written as ``contact-sheet.png`` beside the manifest after
every run, from the items its manifest says are done."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..imageio import write_png

THUMB = 256  # pixels of a thumbnail's height
LABEL = 18  # pixels of the band above each thumbnail


def contact_sheet(folder: Path, done: dict[str, dict]) -> Path | None:
    """Write ``folder/contact-sheet.png`` from the ``done`` events (item -> event); None when there
    is nothing to show."""
    from PIL import Image, ImageDraw, ImageOps

    rows: dict[str, list[tuple[str, Path]]] = {}
    originals: dict[str, Path] = {}
    for item, event in sorted(done.items()):
        photo, look = item.split("/", 1)
        png = folder / event["outputs"][0]
        if png.is_file():
            rows.setdefault(photo, []).append((look, png))
            originals[photo] = Path(event["photo"])
    if not rows:
        return None
    looks = sorted({look for row in rows.values() for look, _ in row})
    cells = [[("photo", originals[p])] + [next(((lk, png) for lk, png in rows[p] if lk == look), (look, None)) for look in looks]
             for p in sorted(rows)]
    width = max(_thumb_width(png) for row in cells for _, png in row if png is not None)
    sheet = Image.new("RGB", (width * (len(looks) + 1), (THUMB + LABEL) * len(cells)), (24, 24, 24))
    draw = ImageDraw.Draw(sheet)
    for r, row in enumerate(cells):
        for c, (label, png) in enumerate(row):
            x, y = c * width, r * (THUMB + LABEL)
            draw.text((x + 4, y + 3), label[:40], fill=(220, 220, 220))
            if png is None or not Path(png).is_file():
                continue
            with Image.open(png) as im:
                im = ImageOps.exif_transpose(im).convert("RGB")  # a photo as it is seen
                im.thumbnail((width, THUMB))
                sheet.paste(im, (x + (width - im.width) // 2, y + LABEL))
    return write_png(folder / "contact-sheet.png", np.asarray(sheet, np.float32) / 255.0)


def _thumb_width(png: Path) -> int:
    from PIL import Image

    with Image.open(png) as im:
        return max(1, round(im.width * THUMB / im.height))
