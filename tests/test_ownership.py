"""The program replaces only what it wrote (viewer/ownership.py): a scene bundle's folder is replaced
when it holds exactly the files this program put there; a user's file beside a scene.json, a note added
to a bundle or an edited map make it the user's. Temporary folders never collide, and two writers to one
output take turns."""

from __future__ import annotations

import subprocess
import sys
import threading

import pytest

from viewer.errors import InputError
from viewer.photo.inference import bundle_target
from viewer.ownership import MARKER, folder_lock, fresh_sibling, mark_written, written_here
from viewer.resources import asset_dir

RELIGHT = [sys.executable, "-m", "viewer.cli.main"]


def _bundle(folder):
    folder.mkdir()
    (folder / "scene.json").write_text('{"format": "relight-scene"}')
    (folder / "albedo.exr").write_bytes(b"\x76\x2f\x31\x01" + bytes(100))
    mark_written(folder)
    return folder


def test_only_an_untouched_bundle_of_ours_may_be_replaced(tmp_path):
    ours = _bundle(tmp_path / "ours")
    assert written_here(ours) and bundle_target(ours) == ours.resolve()
    for spoil in ("a user's note beside it", "an edited map", "a broken marker", "a marker of another list", "a folder in it"):
        b = _bundle(tmp_path / spoil.replace(" ", "_").replace("'", ""))
        if spoil == "a user's note beside it":
            (b / "thesis.txt").write_text("mine")
        elif spoil == "an edited map":
            (b / "albedo.exr").write_bytes(b"changed")
        elif spoil == "a broken marker":
            (b / MARKER).write_text("{")
        elif spoil == "a marker of another list":
            (b / MARKER).write_text((b / MARKER).read_text().replace("albedo.exr", "normal.exr"))
        else:
            (b / "sub").mkdir()
        assert not written_here(b), spoil
        with pytest.raises(InputError, match="relight did not write") as info:
            bundle_target(b)
        assert "\n" not in str(info.value) and str(b) in str(info.value)
    user = tmp_path / "proj"
    user.mkdir()
    (user / "scene.json").write_text("{}")
    (user / "thesis.txt").write_text("mine")
    with pytest.raises(InputError, match="did not write"):
        bundle_target(user)
    assert (user / "thesis.txt").read_text() == "mine"


def test_temporary_folders_never_collide_and_writers_take_turns(tmp_path):
    users = tmp_path / ".out.partial"
    users.mkdir()  # a user's folder with the name the old code used
    made = {fresh_sibling(tmp_path / "out", "partial") for _ in range(50)}
    assert len(made) == 50 and users not in made and all(p.is_dir() for p in made)
    order = []

    def writer(k):
        with folder_lock(tmp_path):
            order.append(("in", k))
            threading.Event().wait(0.05)
            order.append(("out", k))

    threads = [threading.Thread(target=writer, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(order[i][0] == "in" and order[i + 1] == ("out", order[i][1]) for i in range(0, 8, 2))  # never interleaved


def test_two_infers_into_one_folder_leave_one_whole_bundle_and_nothing_else(tmp_path):
    photo = asset_dir() / "photos" / "underpass.jpg"
    out = tmp_path / "proj"
    procs = [subprocess.Popen([*RELIGHT, "infer", str(photo), "-o", str(out), "--size", "128"], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], results
    assert written_here(out) and (out / "albedo.exr").is_file() and (out / "inference.json").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["proj"]  # no temporary folder left


def test_a_users_partial_video_and_rig_are_never_written_over(tmp_path):
    from viewer.lighting.placed_lights import rig, save_rig
    from viewer.resources import sample_scene_dir

    env = str(asset_dir() / "envmaps" / "venice_sunset_256.hdr")
    mine = tmp_path / "v.partial.mp4"
    mine.write_bytes(b"my own video")
    res = subprocess.run([*RELIGHT, "render", str(sample_scene_dir()), "--env", env, "--frames", "2", "--size", "64",
                          "-o", str(tmp_path / "v.mp4")], capture_output=True, text=True, timeout=300)
    assert res.returncode == 2 and "v.partial.mp4: exists" in res.stderr and res.stderr.count("\n") == 1
    assert mine.read_bytes() == b"my own video" and not (tmp_path / "v.mp4").exists()
    rig_file = save_rig(tmp_path / "r.exr", rig("key", 1.0))  # a rig under a name the render's EXR would take
    before = rig_file.read_bytes()
    res = subprocess.run([*RELIGHT, "render", str(sample_scene_dir()), "--env", env, "--rig", str(rig_file), "--size", "64",
                          "-o", str(tmp_path / "r.png")], capture_output=True, text=True, timeout=300)
    assert res.returncode == 2 and "r.exr" in res.stderr and rig_file.read_bytes() == before


def test_an_output_keeps_the_case_the_user_typed(tmp_path):
    from viewer.resources import sample_scene_dir

    lights = asset_dir() / "envmaps" / "venice_sunset_256.lights.json"
    res = subprocess.run([*RELIGHT, "render", str(sample_scene_dir()), str(lights), "--size", "64", "-o", str(tmp_path / "r.PNG")],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.PNG", "r.exr", "r_passes.png"]


def test_a_transparent_video_is_refused_in_one_line_not_written_black(tmp_path):
    from viewer.resources import sample_scene_dir

    env = asset_dir() / "envmaps" / "venice_sunset_256.hdr"
    res = subprocess.run([*RELIGHT, "render", str(sample_scene_dir()), "--env", str(env), "--background", "transparent",
                          "--frames", "2", "-o", str(tmp_path / "v.mp4")], capture_output=True, text=True, timeout=300)
    assert res.returncode == 2 and "no transparency" in res.stderr and res.stderr.count("\n") == 1
    assert not list(tmp_path.iterdir())


def test_a_failed_command_leaves_no_folder_behind(tmp_path):
    res = subprocess.run([*RELIGHT, "render", str(asset_dir() / "envmaps" / "venice_sunset_256.hdr"), "-o",
                          str(tmp_path / "new" / "sub" / "x.png")], capture_output=True, text=True, timeout=300)
    assert res.returncode == 2 and not (tmp_path / "new").exists()
    (tmp_path / "a-file").write_text("x")
    res = subprocess.run([*RELIGHT, "render", str(asset_dir() / "sample_scene"), "--env",
                          str(asset_dir() / "envmaps" / "venice_sunset_256.hdr"), "-o", str(tmp_path / "a-file" / "x.png")],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 2 and "is a file, not a folder" in res.stderr and (tmp_path / "a-file").read_text() == "x"
