"""A batch's contact sheet: a row per photo (the photo, then each of its looks as the batch rendered
it), the look's name over each column; written as ``contact-sheet.png`` beside the manifest after a
run that rendered something, from the items of this run's plan that are done, the first
``MAX_ROWS`` photos. It is a picture to look at: an image it cannot read is left blank, and a
``contact-sheet.png`` the batches did not write is kept (a warning says so)."""

from __future__ import annotations

from pathlib import Path

from viewer.files.imageio import atomic_path, png_mark

SHEET = "contact-sheet.png"
THUMB = 256  # pixels of a thumbnail's height
LABEL = 18  # pixels of the band above each thumbnail
MAX_ROWS = 200


def contact_sheet(folder: Path, done: dict[str, dict], ownership) -> Path | None:
    """Write ``folder/contact-sheet.png`` from the ``done`` events (item -> event); None when there
    is nothing to show or the file there is not the batches' (``ownership``: manifest.Ownership)."""
    import sys

    from PIL import Image, ImageDraw, ImageOps, UnidentifiedImageError

    path = folder / SHEET
    if path.exists() and not ownership.ours(folder, SHEET):
        print(f"relight: warning: {path}: kept (no relight batch wrote it): no contact sheet this time", file=sys.stderr)
        return None

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
             for p in sorted(rows)[:MAX_ROWS]]
    width = max([_thumb_width(png) for row in cells for _, png in row[1:] if png is not None] + [1])
    sheet = Image.new("RGB", (width * (len(looks) + 1), (THUMB + LABEL) * len(cells)), (24, 24, 24))
    draw = ImageDraw.Draw(sheet)
    for r, row in enumerate(cells):
        for c, (label, png) in enumerate(row):
            x, y = c * width, r * (THUMB + LABEL)
            draw.text((x + 4, y + 3), label[:40], fill=(220, 220, 220))
            if png is None:  # this photo has no such look done
                continue
            try:
                with Image.open(png) as im:
                    im = ImageOps.exif_transpose(im).convert("RGB")  # a photo as it is seen
                    im.thumbnail((width, THUMB))
            except (OSError, UnidentifiedImageError, ValueError):
                continue  # moved, changed or unreadable since: left blank
            sheet.paste(im, (x + (width - im.width) // 2, y + LABEL))
    with atomic_path(path) as tmp:
        sheet.save(tmp, format="PNG", pnginfo=png_mark())
    return path


def _thumb_width(png: Path) -> int:
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(png) as im:
            return max(1, round(im.width * THUMB / im.height))
    except (OSError, UnidentifiedImageError, ValueError, ZeroDivisionError):
        return 1
