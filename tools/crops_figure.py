"""Make a before / after figure of 100 % crops of relit photos: the hair, a gap between the limbs,
the darkest cloth and the feet of each person, the crops placed from the photo alone (the pose
model's landmarks and the matte), so any photo and any pair of renders can be compared.

Each argument group is a photo, then its renders to compare, each ``LABEL=IMAGE`` (PNG at the
photo's output frame, as ``relight render`` writes it); ``--parts`` picks some of the crops. Run
from the project root::

    .venv/bin/python -m tools.crops_figure OUT.jpg [--parts "dark cloth,feet"] PHOTO before=A.png now=B.png [PHOTO ...]

docs/photos.md shows its figures (the "before" renders from the product of the previous issue).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

CROP = 0.09  # of the person's height: the side of each square crop
PARTS = ("hair", "limb gap", "dark cloth", "feet")


def crop_boxes(photo: np.ndarray) -> dict:
    """name -> (top, left, side) of the four crops of ``photo`` (uint8 sRGB at its output frame)."""
    import cv2

    from viewer.photo.matting import automatic_matte
    from viewer.photo.pose_masks import person_height
    from viewer.photo.segmentation import find_person

    person = find_person(photo)
    alpha = automatic_matte(photo, person).alpha
    h, w = alpha.shape
    side = max(int(CROP * person_height(alpha > 0.5)), 32)
    lm = {i: (x * w, y * h) for i, (x, y) in person.landmarks.items()}

    def around(x, y, size=side):
        return (int(np.clip(y - size / 2, 0, h - size)), int(np.clip(x - size / 2, 0, w - size)), size)

    boxes = {}
    ear = max((i for i in (7, 8) if i in lm), key=lambda i: abs(lm[i][0] - lm.get(0, (w / 2, 0))[0]), default=None)
    if ear is not None:  # below and beside the ear: hair over the shoulder against the background
        boxes["hair"] = around(lm[ear][0] + (lm[ear][0] - lm.get(0, lm[ear])[0]), lm[ear][1] + 0.6 * side)
    best = None
    for i, j in ((13, 23), (14, 24), (25, 26)):  # each arm and the body, the legs
        if i in lm and j in lm:  # the background the matte leaves between them
            t = np.linspace(0.1, 0.9, 33)[:, None]
            points = np.array(lm[i]) * (1 - t) + np.array(lm[j]) * t
            inside = [(x, y) for x, y in points if 0 <= int(y) < h and 0 <= int(x) < w and alpha[int(y), int(x)] < 0.5]
            if inside and (best is None or len(inside) > len(best)):
                best = inside
    if best:
        boxes["limb gap"] = around(*np.mean(best, axis=0))
    grey = cv2.cvtColor(photo, cv2.COLOR_RGB2GRAY).astype(np.float32)
    solid = (alpha > 0.99).astype(np.float32)
    mean = cv2.boxFilter(grey * solid, -1, (side, side)) / np.maximum(cv2.boxFilter(solid, -1, (side, side)), 1e-6)
    mean[cv2.boxFilter(solid, -1, (side, side)) < 0.6] = np.inf  # mostly person
    y, x = np.unravel_index(np.argmin(mean), mean.shape)
    boxes["dark cloth"] = around(x, y)
    feet = [lm[i] for i in (29, 30, 31, 32) if i in lm]
    if feet:  # twice as large, down to the ground under the soles
        size = min(2 * side, h, w)
        boxes["feet"] = around(np.mean([p[0] for p in feet]), max(p[1] for p in feet) + 0.1 * size, size)
    return boxes


def figure(groups: list, out: Path, tile: int = 300, parts=PARTS) -> Path:
    """Rows of (photo, {label: image}): per photo and part, the crop of each render side by side."""
    from viewer.files.imageio import read_png, write_jpeg
    from viewer.output.render import _label
    from viewer.photo.frames import output_frame, read_photo
    from viewer.resize import resize

    rows = []
    for photo_path, renders in groups:
        photo = read_photo(photo_path, [])
        frame = output_frame((photo.shape[1], photo.shape[0]))
        photo = resize(photo, frame)
        boxes = crop_boxes(photo)
        images = {label: read_png(path)[..., :3] for label, path in renders.items()}
        for part in parts:
            if part not in boxes:
                continue
            top, left, side = boxes[part]
            tiles = [_label(resize(photo[top:top + side, left:left + side].astype(np.float32) / 255.0, (tile, tile)),
                            f"{Path(photo_path).stem[-8:]}: {part}, photo")]
            for label, image in images.items():
                tiles.append(_label(resize(image[top:top + side, left:left + side].astype(np.float32), (tile, tile)), label))
            rows.append(np.concatenate(tiles, axis=1))
    width = max(r.shape[1] for r in rows)
    rows = [np.pad(r, ((0, 4), (0, width - r.shape[1]), (0, 0)), constant_values=1.0) for r in rows]
    return write_jpeg(out, np.concatenate(rows, axis=0))


def main(argv: list) -> int:
    if len(argv) < 3:
        print(__doc__)
        return 2
    groups, current, parts = [], None, PARTS
    rest = argv[1:]
    if rest[:1] == ["--parts"]:
        parts, rest = tuple(p.strip() for p in rest[1].split(",")), rest[2:]
    for arg in rest:
        if "=" in arg:
            label, path = arg.split("=", 1)
            current[1][label] = path
        else:
            current = (arg, {})
            groups.append(current)
    print(f"wrote {figure(groups, Path(argv[0]), parts=parts)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
