"""The person a clip bundle relights: chosen once in the clip's first frames (the largest and most
central, or the one at the user's point), shown in a preview, and the frames they are missing from."""

from __future__ import annotations

from pathlib import Path

from viewer.files.clip_reader import clip_frames
from viewer.files.imageio import write_png
from viewer.photo.frames import output_frame
from viewer.resize import resize
from viewer.scene.clip_bundle import (
    FRAMES,
    frame_name,
    read_frame_entry,
)

PREVIEW = "person.png"  # the clip's first frame with anyone, the person chosen outlined, the others dimmed
CHOOSE_WITHIN = 300  # frames: how far into the clip the person to relight is looked for


def choose_person(clip_path, out_dir: Path, start: float, end: float | None, max_size: int, point: tuple | None) -> dict | None:
    """The person the clip relights, chosen on its first frame with anyone in it (within
    ``CHOOSE_WITHIN`` frames; :func:`viewer.photo.person_track.choose`, ``point`` given or not),
    with the preview written into ``out_dir``: what the record keeps ("person"), or None when no
    one is seen there (each frame then relights whom it finds)."""
    from viewer.photo.person_track import choose, preview
    from viewer.photo.segmentation import frame_people

    for frame in clip_frames(clip_path, start, end):
        if frame.index >= CHOOSE_WITHIN:
            break
        if frame.rgb is None:
            continue
        small, masks, parts = frame_people(resize(frame.rgb, output_frame((frame.rgb.shape[1], frame.rgb.shape[0]), max_size)),
                                           clip_path)
        pick = choose(parts, point)
        if pick is None:
            continue
        write_png(out_dir / PREVIEW, preview(small, masks, pick))
        box = parts[pick].box
        return {"frame": frame.index, "seconds": round(frame.seconds, 6), "box": [round(float(v), 5) for v in box],
                "signature": [round(float(v), 6) for v in parts[pick].signature], "others": len(parts) - 1,
                "point": None if point is None else list(point)}
    return None


def person_said(clip_path, record: dict, out_dir: Path) -> str:
    """One line: whom the clip relights (record's "person", :func:`choose_person`), and how to choose otherwise."""
    chosen, options = record.get("person"), record["options"]
    if chosen is None:
        return f"{clip_path}: no one seen in its first {CHOOSE_WITHIN} frames; each frame relights the person it finds"
    x, y, w, h = chosen["box"]
    how = "under --person" if chosen.get("point") else "the largest and most central"
    who = "everyone (--people all)" if options.get("people") == "all" else \
        f"the person at {100 * (x + w / 2):.0f} % across, {100 * h:.0f} % of the frame's height tall ({how})"
    others = chosen.get("others", 0)
    rest = (f"; {others} other{'s' if others != 1 else ''} there left out (--person X,Y chooses another, --people all "
            "relights everyone)") if others and options.get("people") != "all" else ""
    at = chosen["seconds"] + float(options["start"])
    return f"{clip_path}: relighting {who}, first seen at {at:.2f} s{rest}; preview: {Path(out_dir) / PREVIEW}"


def person_gaps(clip_path, out_dir: Path, record: dict) -> list[str]:
    """One line per run of frames without the person (the frame's state "no person") of a complete
    ``record``, with its frames and times on the clip's clock: the relit clip shows the new
    background alone there."""
    gaps, run, count, start = [], None, int(record["frames"]), float(record["options"]["start"])
    for i in range(count):
        entry = read_frame_entry(Path(out_dir) / FRAMES / f"{frame_name(i)}.json")
        if entry.state == "no person":
            run = [entry, entry] if run is None else [run[0], entry]
        if run is not None and (entry.state != "no person" or i == count - 1):
            a, b = run
            frames = f"frame {a.index}" if a.index == b.index else f"frames {a.index}-{b.index}"
            gaps.append(f"{clip_path}: no one relit in {frames} ({a.seconds + start:.2f}-{b.seconds + start:.2f} s): {a.note}; "
                        "the new background alone there")
            run = None
    return gaps
