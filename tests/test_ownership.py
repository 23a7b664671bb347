"""The program replaces only what it wrote (viewer/files/ownership.py): a scene bundle's folder is replaced
when it holds exactly the files this program put there; a user's file beside a scene.json, a note added
to a bundle or an edited map make it the user's. Temporary folders never collide, and two writers to one
output take turns."""

from __future__ import annotations

import subprocess
import sys
import threading

import pytest

from viewer.errors import InputError
from viewer.files.ownership import MARKER, folder_lock, fresh_sibling, mark_written, written_here
from viewer.photo.inference import bundle_target
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


def test_every_file_written_carries_the_mark_and_only_marked_files_are_ours(tmp_path):
    """PNG, JPEG, EXR, JSON light files and MP4 videos written by the program are its own; the same
    formats written by anything else (or damaged) are not."""
    import numpy as np
    from PIL import Image

    from viewer.files.imageio import write_exr, write_jpeg, write_png
    from viewer.files.ownership import file_is_ours
    from viewer.output.video import VideoWriter
    from viewer.scene.area_lights import load_lights

    image = np.full((8, 8, 3), 0.5, np.float32)
    ours = [write_png(tmp_path / "a.png", image), write_jpeg(tmp_path / "a.jpg", image), write_exr(tmp_path / "a.exr", image),
            load_lights(asset_dir() / "envmaps" / "venice_sunset_256.lights.json").save(tmp_path / "a.json")]
    with VideoWriter(tmp_path / "a.mp4", 16, 16, 10) as video:
        video.write(np.zeros((16, 16, 3), np.uint8))
    ours.append(tmp_path / "a.mp4")
    assert all(file_is_ours(p) for p in ours)
    Image.new("RGB", (8, 8)).save(tmp_path / "b.png")
    Image.new("RGB", (8, 8)).save(tmp_path / "b.jpg")
    (tmp_path / "b.json").write_text('{"format": "relight-lights", "lights": []}')
    (tmp_path / "b.exr").write_bytes((tmp_path / "a.exr").read_bytes()[:40])
    (tmp_path / "b.mp4").write_bytes(b"not a video")
    (tmp_path / "b.txt").write_text("mine")
    assert not any(file_is_ours(tmp_path / f"b{s}") for s in (".png", ".jpg", ".json", ".exr", ".mp4", ".txt"))
    assert not file_is_ours(tmp_path / "missing.png")


def test_render_replaces_its_own_files_and_refuses_a_users_file_beside_them(tmp_path):
    """Rendering again to one -o replaces the PNG, EXR and passes sheet it wrote; a user's
    portrait.exr or portrait_passes.png at those paths is refused in one line naming it (exit 2), kept
    byte for byte, unless --force."""
    from viewer.resources import sample_scene_dir

    lights = str(asset_dir() / "envmaps" / "venice_sunset_256.lights.json")
    out = tmp_path / "portrait.png"
    cmd = [*RELIGHT, "render", str(sample_scene_dir()), lights, "--size", "64", "-o", str(out)]
    for _ in range(2):
        res = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        assert res.returncode == 0, res.stderr
    for name in ("portrait.exr", "portrait_passes.png", "portrait.png"):
        for p in tmp_path.iterdir():
            p.unlink()
        (tmp_path / name).write_bytes(b"the user's own")
        res = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        assert res.returncode == 2 and name in res.stderr and "--force" in res.stderr and res.stderr.count("\n") == 1
        assert (tmp_path / name).read_bytes() == b"the user's own" and sorted(p.name for p in tmp_path.iterdir()) == [name]
    res = subprocess.run(cmd + ["--force"], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "portrait.png").read_bytes() != b"the user's own"


def test_fit_lights_keeps_a_hand_written_light_file_and_stale_lights_are_not_used(tmp_path, monkeypatch):
    """A MAP.lights.json the user wrote (no mark, no fit record) is kept: fit-lights puts the lights in
    the cache and says so, and -o at it is refused. Lights fitted beside a map serve that map only:
    the map replaced by another under the same name, they are not used (render fits the new map)."""
    import json
    import shutil

    monkeypatch.setenv("RELIGHT_CACHE", str(tmp_path / "cache"))
    maps = asset_dir() / "envmaps"
    sky = shutil.copyfile(maps / "venice_sunset_256.hdr", tmp_path / "sky.hdr")
    mine = tmp_path / "sky.lights.json"
    hand = {"format": "relight-lights", "note": "my key light", "lights": [{"direction": [0, 1, 0], "sigma": 1, "intensity": [1, 1, 1]}]}
    mine.write_text(json.dumps(hand))
    res = subprocess.run([*RELIGHT, "fit-lights", str(sky), "-n", "4"], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert json.loads(mine.read_text()) == hand and "the fitting cache" in res.stdout and str(mine) in res.stdout
    res = subprocess.run([*RELIGHT, "fit-lights", str(sky), "-n", "4", "-o", str(mine)], capture_output=True, text=True, timeout=300)
    assert res.returncode == 2 and "sky.lights.json" in res.stderr and json.loads(mine.read_text()) == hand
    mine.unlink()
    res = subprocess.run([*RELIGHT, "fit-lights", str(sky), "-n", "4"], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0 and f"-> {mine}" in res.stdout
    from viewer.lighting.envmap import load_envmap
    from viewer.lighting.map_lights import sidecar_lights

    assert sidecar_lights(load_envmap(sky), sky, 4, "instant") is not None
    shutil.copyfile(maps / "immenstadter_horn_256.hdr", sky)  # another map under the same name
    assert sidecar_lights(load_envmap(sky), sky, 4, "instant") is None
    res = subprocess.run([*RELIGHT, "render", str(asset_dir() / "sample_scene"), "--env", str(sky), "-n", "4", "--size", "64",
                          "-o", str(tmp_path / "r.png")], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0 and "shipped beside the map" not in res.stdout, res.stdout + res.stderr


def test_two_renders_to_one_output_at_once_leave_one_renders_files(tmp_path):
    """Two renders under different lights into one -o at once: the PNG, EXR and passes sheet left are
    all one render's (each the same bytes as that render alone writes), never a mix (issue 43); the one that
    finds the output held is refused in one line naming the other (issue 62), or both finish one after the other."""
    import hashlib

    from viewer.resources import sample_scene_dir

    maps = asset_dir() / "envmaps"
    sets = [str(maps / "venice_sunset_256.lights.json"), str(maps / "studio_small_03_256.lights.json")]

    def cmd(lights, out):
        return [*RELIGHT, "render", str(sample_scene_dir()), lights, "--size", "64", "-o", str(out)]

    def triplet(folder):
        return tuple(hashlib.sha256((folder / n).read_bytes()).hexdigest() for n in ("r.png", "r.exr", "r_passes.png"))

    alone = []
    for k, lights in enumerate(sets):
        (tmp_path / f"alone{k}").mkdir()
        assert subprocess.run(cmd(lights, tmp_path / f"alone{k}" / "r.png"), capture_output=True, timeout=300).returncode == 0
        alone.append(triplet(tmp_path / f"alone{k}"))
    assert alone[0] != alone[1]
    both = tmp_path / "both"
    for _ in range(3):
        procs = [subprocess.Popen(cmd(lights, both / "r.png"), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE) for lights in sets]
        ended = [(p.wait(300), p.stderr.read().decode()) for p in procs]
        assert any(code == 0 for code, _ in ended)
        assert all(code == 0 or (code == 2 and "is being written by another relight (process" in err and err.count("\n") == 1)
                   for code, err in ended), ended
        assert triplet(both) in alone
        assert sorted(p.name for p in both.iterdir()) == ["r.exr", "r.png", "r_passes.png"]
