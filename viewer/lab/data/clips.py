"""``relight dataset make --split clip``: a synthetic person turning in place, filmed under one map
(the input clip) and rendered under a second (the truth), for measuring a relit clip against what it
should be (``relight bench video --truth DIR``).

Layout, beside the held-out split's ``DIR/maps/``::

    DIR/clips/<index>/input/NNNNNN.exr    frame NNNNNN under the input map, the map seen behind the
                                          person (a photo of them there), linear RGB, the clip's exposure
    DIR/clips/<index>/truth/NNNNNN.exr    the same frame under the truth map: the person alone, linear
                                          RGB and their coverage (A), the same exposure
    DIR/clips/<index>/input.mp4           the input frames as a camera records them: sRGB, 8 bit, H.264
    DIR/clips/<index>/plan.json           what its frames are made with (settings, maps, turns): first
    DIR/clips/<index>/exposure.json       the clip's exposure (written with its first frame)
    DIR/clips/<index>/clip.json           maps, yaws, the person's turn per frame, fps; written last

The person (the held-out split's person of the same seed and index: body, pose and clothes) turns
by ``SWEEP`` degrees over the clip about their own turn, the camera still. Both maps are drawn from
the held-out maps (``--maps``, two different ones) and turned by a random longitude each. The
exposure is one for the clip: the input's first frame's person at a median luminance of 0.18.
A stopped run keeps every frame it finished (both EXRs); the MP4 and the record are made once all
are there. Everything is a function of (seed, index), as the other splits.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.files.imageio import read_exr, write_exr, write_text
from viewer.lab.data.people import TURN_RANGE, make_person, person_draws
from viewer.lighting.envmap import LUMINANCE

SWEEP = 60.0  # degrees the person turns over the clip
MEDIAN = 0.18  # the input's first frame: the person's median luminance after the exposure


def clip_dir(out, index: int) -> Path:
    return Path(out) / "clips" / f"{index:06d}"


def clip_plan(seed: int, index: int, pool_size: int, frames: int) -> dict:
    """What clip ``index`` is made of: its person's seed, the two maps (indices into the pool), their
    yaws, the person's turn at each frame."""
    person_seed = seed * 1_000_003 + index
    rng = np.random.default_rng([person_seed, 0xC11F])
    if pool_size < 2:
        raise ValueError("the clip split needs two maps or more")
    a, b = (int(k) for k in rng.choice(pool_size, 2, replace=False))
    turn = person_draws(person_seed)[4]
    middle = float(np.clip(turn, TURN_RANGE[0] + SWEEP / 2, TURN_RANGE[1] - SWEEP / 2))
    direction = 1.0 if rng.uniform() < 0.5 else -1.0
    turns = [middle + direction * SWEEP * (k / max(frames - 1, 1) - 0.5) for k in range(frames)]
    return {"person_seed": person_seed, "input_map": a, "truth_map": b, "input_yaw": float(rng.uniform(0.0, 360.0)),
            "truth_yaw": float(rng.uniform(0.0, 360.0)), "turns": turns}


def frame_file(clip: Path, part: str, k: int) -> Path:
    """Frame ``k``'s EXR of the clip in folder ``clip``: ``part`` "input" or "truth"."""
    return Path(clip) / part / f"{k:06d}.exr"


def make_clip(cfg, index: int, pool, progress=None) -> dict:
    """Write clip ``index`` of the dataset ``cfg`` (its frames kept from a stopped run, a clip made with
    other settings refused); returns its record and how many frames were made now."""
    from viewer.lab.data.truth import render_frame
    from viewer.output.video import VideoWriter

    out = clip_dir(cfg.out, index)
    plan = clip_plan(cfg.seed, index, len(pool), cfg.frames)
    inp, truth = pool[plan["input_map"]], pool[plan["truth_map"]]
    made = {"res": cfg.res, "spp": cfg.spp, "fps": cfg.fps, "seed": cfg.seed, "maps": [p.name for p in pool], **plan}
    plan_file = out / "plan.json"  # what the frames there were made with: a run with other settings is refused
    if plan_file.is_file() and json.loads(plan_file.read_text()) != json.loads(json.dumps(made)):
        raise InputError(out, "holds a clip made with other settings (--res, --spp, --frames, --seed or the maps): "
                              "give another --out, or the settings it was made with")
    if not plan_file.is_file():
        write_text(plan_file, json.dumps(made) + "\n")
    exposure_file = out / "exposure.json"  # written with the first frame, before its images: one for the clip
    rendered = 0
    for k, turn in enumerate(plan["turns"]):
        files = frame_file(out, "input", k), frame_file(out, "truth", k)
        if not (exposure_file.is_file() and all(f.is_file() for f in files)):
            person = make_person(plan["person_seed"], cfg.res, turn=turn)
            seed = (plan["person_seed"] + k) % 2**32
            shown = render_frame(person, inp.env, plan["input_yaw"], cfg.spp, seed, background=True)
            relit = render_frame(person, truth.env, plan["truth_yaw"], cfg.spp, seed)
            if not exposure_file.is_file():  # the first frame (frames are made in order, each after the one before)
                write_text(exposure_file, json.dumps({"exposure": _exposure(shown, relit[..., 3])}) + "\n")
            exposure = float(json.loads(exposure_file.read_text())["exposure"])
            relit[..., :3] *= exposure
            write_exr(files[1], relit)
            write_exr(files[0], shown[..., :3] * exposure)  # last: the frame is there when its input is
            rendered += 1
        if progress is not None:
            progress("frames", k + 1, len(plan["turns"]))
    video = out / "input.mp4"
    if not video.is_file():
        from viewer.files.imageio import linear_to_srgb

        with VideoWriter(video, cfg.res, cfg.res, fps=cfg.fps) as writer:
            for k in range(len(plan["turns"])):
                writer.write(np.clip(linear_to_srgb(read_exr(frame_file(out, "input", k))[..., :3]), 0.0, 1.0))
    record = {"index": index, "seed": plan["person_seed"], "res": cfg.res, "spp": cfg.spp, "fps": cfg.fps,
              "frames": len(plan["turns"]), "turns": plan["turns"],
              "input": {"map": inp.name, "yaw": plan["input_yaw"]}, "truth": {"map": truth.name, "yaw": plan["truth_yaw"]}}
    write_text(out / "clip.json", json.dumps(record, indent=1) + "\n")
    return {**record, "frames_made": rendered}


def _exposure(frame: np.ndarray, coverage: np.ndarray) -> float:
    """The clip's exposure from its first input frame: the person's (``coverage`` > 0.5) median
    luminance to ``MEDIAN``."""
    luminance = frame[..., :3] @ LUMINANCE
    person = coverage > 0.5
    median = float(np.median(luminance[person])) if person.any() else float(np.median(luminance))
    return MEDIAN / max(median, 1e-6)


def read_clip(path) -> dict:
    """A finished dataset clip's record (``clip.json``) with its folder as ``path``."""
    path = Path(path)
    return {**json.loads((path / "clip.json").read_text()), "path": path}
