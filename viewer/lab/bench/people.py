"""``relight bench people``: is the person a clip relights the same one in every frame?

Each clip is read as ``relight infer CLIP`` reads it: its person chosen once
(:func:`viewer.photo.clip_person.choose_person`, the preview written beside the JSON), then
followed frame by frame through the product's own person finding
(:func:`viewer.photo.segmentation.find_person` with the clip's
:class:`viewer.photo.person_track.PersonTrack`), which is what decides whom every frame's matte
holds (the matte then only refines the outline). Against a clip's truth (``CLIP.json`` beside it:
per frame whether the person is in the picture, their box and the others' boxes, in the clip's
pixels), per frame:

- *missing*: the person is in the picture (and at least half of them visible) but no one is
  relit, or under half of what is relit lies in their box;
- *swapped*: more than half of what is relit lies in other people's boxes, outside the person's
  (or anyone is relit while the person is out of the picture);
- *beside*: another person relit beside them (10-50 % of what is relit in the others' boxes);
- *away*: the person out of the picture and no one relit (right).

A clip without truth gets what can be told without it: the frames with no one relit, and the
frames where what is relit jumps (its box's centre moves more than half its height from one frame
to the next: a swap, or the person reappearing elsewhere). Strips of frames (what is relit
outlined in green, the truth's boxes: the person white, others red) go beside the JSON, to look
at: the clips' terms keep them out of the docs.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from viewer.errors import NoPersonError

STRIP_FRAMES = 8  # frames a clip's strip shows, evenly spread
STRIP_HEIGHT = 240  # pixels
BOX_MARGIN = 0.1  # of the truth box's size, each side: a raised hand just outside it is still theirs


def _inside(mask: np.ndarray, box, scale: float) -> np.ndarray:
    """(H, W) bool: ``box`` (x0, y0, x1, y1 in the clip's pixels, scaled by ``scale`` to the mask's)
    grown by ``BOX_MARGIN``, as a mask the shape of ``mask``."""
    h, w = mask.shape
    x0, y0, x1, y1 = (v * scale for v in box)
    mx, my = BOX_MARGIN * (x1 - x0), BOX_MARGIN * (y1 - y0)
    out = np.zeros((h, w), bool)
    out[max(int(y0 - my), 0):min(int(np.ceil(y1 + my)), h), max(int(x0 - mx), 0):min(int(np.ceil(x1 + mx)), w)] = True
    return out


def judge(relit: np.ndarray | None, truth: dict, index: int, scale: float) -> str:
    """What frame ``index`` relit against the clip's ``truth``: "right", "missing", "swapped",
    "beside" or "away" (the module docstring); ``relit`` (H, W) bool or None (no one relit),
    ``scale``: the truth's pixels to ``relit``'s."""
    in_picture = bool(truth["person_in_picture"][index])
    visible = float((truth.get("person_visible_fraction") or [1.0] * (index + 1))[index])
    if relit is None or not relit.any():
        return "missing" if in_picture and visible >= 0.5 else "away"
    area = float(relit.sum())
    person = _inside(relit, truth["person_box"][index], scale) if in_picture else np.zeros_like(relit)
    others = np.zeros_like(relit)
    for box in truth["other_boxes"][index]:
        others |= _inside(relit, box, scale)
    others &= ~person
    in_others = float((relit & others).sum()) / area
    if in_others > 0.5 or not in_picture:
        return "swapped"
    if float((relit & person).sum()) / area < 0.5:
        return "missing"
    return "beside" if in_others > 0.1 else "right"


def follow_clip(clip: Path, out_dir: Path, max_size: int, progress=print) -> dict:
    """The person ``clip`` relights in every frame, found as the product finds them: per frame the
    state and the relit mask at the bundle's frame size (kept only for the strip and the truth)."""
    from viewer.files.clip_reader import clip_frames
    from viewer.photo.clip_person import choose_person
    from viewer.photo.frames import output_frame
    from viewer.photo.person_track import PersonTrack
    from viewer.photo.segmentation import find_person
    from viewer.resize import resize

    folder = out_dir / clip.stem
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    chosen = choose_person(clip, folder, 0.0, None, max_size, None)
    follow = PersonTrack(chosen) if chosen else None
    frames = []
    for frame in clip_frames(clip, 0.0, None):
        if frame.rgb is None:
            frames.append({"index": frame.index, "relit": None, "note": "lost", "picture": None})
            continue
        picture = resize(frame.rgb, output_frame((frame.rgb.shape[1], frame.rgb.shape[0]), max_size))
        if follow is not None:
            follow.at(frame.index)
        try:
            relit = find_person(picture, f"{clip} frame {frame.index}", [], follow=follow).segmentation > 0.5
            note = ""
        except NoPersonError as exc:
            relit, note = None, exc.problem
        frames.append({"index": frame.index, "relit": relit, "note": note, "picture": picture})
        if frame.index % 25 == 0:
            progress(f"  {clip.name}: frame {frame.index}")
    return {"chosen": chosen, "frames": frames, "seconds": time.perf_counter() - t0, "folder": folder}


def _jumps(frames: list[dict]) -> list[int]:
    """Frames whose relit box's centre moved more than half its height from the frame before's."""
    from viewer.photo.frames import person_box

    jumps, before = [], None
    for f in frames:
        relit = f["relit"]
        if relit is None or not relit.any():
            before = None
            continue
        top, left, tall, wide = person_box(relit)
        centre = (left + wide / 2, top + tall / 2, tall)
        if before is not None and np.hypot(centre[0] - before[0], centre[1] - before[1]) > 0.5 * max(before[2], 1):
            jumps.append(f["index"])
        before = centre
    return jumps


def _strip(frames: list[dict], truth: dict | None, scale_of, out: Path) -> Path:
    """A strip of ``STRIP_FRAMES`` frames: what is relit outlined in green, the truth's boxes drawn."""
    import cv2

    from viewer.files.imageio import write_png
    from viewer.resize import resize

    shown = [f for f in frames if f["picture"] is not None]
    picks = [shown[int(i)] for i in np.linspace(0, len(shown) - 1, min(STRIP_FRAMES, len(shown)))]
    tiles = []
    for f in picks:
        image = f["picture"].copy()
        if f["relit"] is not None:
            edge = cv2.morphologyEx(f["relit"].astype(np.uint8), cv2.MORPH_GRADIENT, np.ones((5, 5), np.uint8)) > 0
            image[edge] = (40, 240, 60)
        if truth is not None:
            s = scale_of(image)
            boxes = ([(truth["person_box"][f["index"]], (255, 255, 255))] if truth["person_in_picture"][f["index"]] else []) + \
                [(b, (230, 40, 40)) for b in truth["other_boxes"][f["index"]]]
            for box, colour in boxes:
                x0, y0, x1, y1 = (int(v * s) for v in box)
                cv2.rectangle(image, (x0, y0), (x1, y1), colour, 2)
        cv2.putText(image, str(f["index"]), (8, 40), cv2.FONT_HERSHEY_SIMPLEX, 1.4, (255, 255, 0), 3)
        h, w = image.shape[:2]
        tiles.append(resize(image, (max(int(w * STRIP_HEIGHT / h), 1), STRIP_HEIGHT)))
    return write_png(out, np.concatenate(tiles, axis=1).astype(np.float32) / 255.0)


def measure_clip(clip: Path, out_dir: Path, max_size: int, progress=print) -> dict:
    """One clip's figures (module docstring), its strip and the preview of whom it chose."""
    followed = follow_clip(clip, out_dir, max_size, progress)
    frames = followed["frames"]
    truth_path = clip.with_suffix(".json")
    truth = json.loads(truth_path.read_text()) if truth_path.is_file() else None

    def scale_of(image: np.ndarray) -> float:
        return image.shape[1] / float(truth["width"])

    row = {"clip": clip.name, "frames": len(frames), "chosen": {k: v for k, v in (followed["chosen"] or {}).items() if k != "signature"},
           "no_one_relit": [f["index"] for f in frames if f["relit"] is None], "jumps": _jumps(frames),
           "seconds_per_frame": round(followed["seconds"] / max(len(frames), 1), 3)}
    if truth is not None:
        states = [judge(f["relit"], truth, f["index"], scale_of(f["picture"])) if f["picture"] is not None else "lost"
                  for f in frames]
        row["truth"] = {state: [i for i, s in enumerate(states) if s == state] for state in
                        ("right", "missing", "swapped", "beside", "away", "lost")}
        row["truth"]["in_picture"] = int(sum(bool(v) for v in truth["person_in_picture"]))
    row["strip"] = str(_strip(frames, truth, scale_of if truth is not None else None, followed["folder"] / "strip.png"))
    return row


def run_people(clips: list[Path], out_dir, max_size: int = 1280, progress=print) -> dict:
    """Every clip of ``clips`` measured (:func:`measure_clip`); ``people.json`` in ``out_dir``."""
    from viewer.files.imageio import write_text

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    rows = []
    for clip in clips:
        progress(f"{clip.name}")
        rows.append(measure_clip(Path(clip), out_dir, max_size, progress))
    result = {"clips": rows, "max_size": max_size, "seconds": round(time.perf_counter() - t0, 1)}
    write_text(out_dir / "people.json", json.dumps(result, indent=1) + "\n")
    return result


def people_table(result: dict) -> str:
    """The figures as a Markdown table."""
    lines = ["| clip | frames | person in picture | missing | swapped | beside | no one relit | jumps | s a frame |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in result["clips"]:
        t = r.get("truth")
        cells = [str(t["in_picture"]), str(len(t["missing"])), str(len(t["swapped"])), str(len(t["beside"]))] if t else ["-"] * 4
        lines.append(f"| {r['clip']} | {r['frames']} | " + " | ".join(cells) +
                     f" | {len(r['no_one_relit'])} | {len(r['jumps'])} | {r['seconds_per_frame']} |")
    return "\n".join(lines)
