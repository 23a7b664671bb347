"""relight batch on real files and real processes: every output and its manifest, a rerun that does
nothing, a bad photo that fails alone, a batch killed with SIGKILL and run again, two batches on one
folder, the compositor's layers read back with OpenEXR, and a local Ray cluster with a worker killed
mid-batch."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from viewer.resources import asset_dir

PHOTO = asset_dir() / "photos" / "underpass.jpg"
MAPS = [asset_dir() / "envmaps" / n for n in ("venice_sunset_256.hdr", "studio_small_03_256.hdr")]


def batch(tmp_path, *args, wait=True, env=None):
    cmd = [sys.executable, "-m", "viewer.cli.main", "batch", *map(str, args), "--max-size", "256"]
    environ = {**os.environ, "RELIGHT_CACHE": str(tmp_path / "cache" / "lights"), **(env or {})}
    if not wait:
        return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=environ)
    return subprocess.run(cmd, capture_output=True, text=True, env=environ, timeout=600)


def events(folder: Path) -> list[dict]:
    return [json.loads(line) for line in (folder / "manifest.jsonl").read_text().splitlines()]


def done_items(folder: Path) -> list[str]:
    return [e["item"] for e in events(folder) if e["event"] == "done"]


def hashes(folder: Path) -> dict:
    import hashlib

    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and p.suffix in (".png", ".exr")}


@pytest.fixture(scope="module")
def first_run(tmp_path_factory):
    """Two photos (one of them not a photo) x two maps, with layers, on two workers."""
    tmp = tmp_path_factory.mktemp("batch")
    photos = tmp / "photos"
    photos.mkdir()
    shutil.copy(PHOTO, photos / "underpass.jpg")
    (photos / "broken.jpg").write_text("not a photo")
    out = tmp / "out"
    res = batch(tmp, photos, "--env", *MAPS, "-o", out, "--workers", "2", "--layers", "--per-light")
    return tmp, photos, out, res


def test_a_batch_writes_every_output_and_its_manifest(first_run):
    tmp, photos, out, res = first_run
    assert res.returncode == 1, res.stderr  # one photo failed
    assert "batch: 2 done, 2 failed, 0 already done" in res.stdout, res.stdout
    for look in ("venice_sunset_256", "studio_small_03_256"):
        for suffix in (".png", ".exr", ".layers.exr"):
            assert (out / "underpass" / f"{look}{suffix}").is_file()
    done = {e["item"]: e for e in events(out) if e["event"] == "done"}
    assert set(done) == {"underpass/venice_sunset_256", "underpass/studio_small_03_256"}
    for e in done.values():
        assert len(e["key"]) == 64 and set(e["sha256"]) == set(e["outputs"]) and e["times"]["render"] > 0
    failed = [e for e in events(out) if e["event"] == "failed"]
    assert sorted(e["item"] for e in failed) == ["broken/studio_small_03_256", "broken/venice_sunset_256"]
    assert all("broken.jpg" in e["error"] and "\n" not in e["error"] for e in failed)  # its line, and its items alone
    assert "relight: broken/venice_sunset_256: " in res.stderr and "Traceback" not in res.stderr
    assert not [p for p in out.rglob("*.tmp")]


def test_a_rerun_does_nothing(first_run):
    tmp, photos, out, res = first_run
    before, lines = hashes(out), len(events(out))
    again = batch(tmp, photos, "--env", *MAPS, "-o", out, "--workers", "2", "--layers", "--per-light")
    assert "batch: 0 done, 2 failed, 2 already done" in again.stdout, again.stdout  # the broken photo fails again
    assert hashes(out) == before
    assert [e["event"] for e in events(out)[lines:]] == ["failed", "failed"]  # the broken photo, tried again


def test_a_changed_input_or_setting_is_done_again_and_a_foreign_file_kept(first_run, tmp_path):
    tmp, photos, out, res = first_run
    again = batch(tmp, photos / "underpass.jpg", "--env", MAPS[0], "-o", out, "--workers", "1", "--layers", "--per-light", "--exposure",
                  "1")
    assert "batch: 1 done, 0 failed, 0 already done" in again.stdout, again.stdout  # another exposure: another key
    (out / "underpass" / "studio_small_03_256.png").write_bytes(b"the user's own file")
    kept = batch(tmp, photos / "underpass.jpg", "--env", MAPS[1], "-o", out, "--workers", "1", "--layers", "--per-light", "--exposure", "1")
    assert kept.returncode == 1 and "exists and no relight batch wrote it there" in kept.stderr
    assert (out / "underpass" / "studio_small_03_256.png").read_bytes() == b"the user's own file"


def test_layers_hold_the_beauty_as_the_sum_of_its_parts(first_run):
    import OpenEXR

    out = first_run[2]
    with OpenEXR.File(str(out / "underpass" / "venice_sunset_256.layers.exr"), separate_channels=True) as f:
        ch = {name: c.pixels.astype(np.float64) for name, c in f.channels().items()}
    for layer in ("person", "albedo", "diffuse", "specular", "unshadowed"):
        assert {f"{layer}.{c}" for c in "RGB"} <= set(ch)
    assert {"R", "G", "B", "A", "person.A", "visibility.Y", "normal.X", "normal.Y", "normal.Z", "depth.Z"} <= set(ch)
    rgb = lambda layer: np.stack([ch[f"{layer}.{c}"] for c in "RGB"], -1)  # noqa: E731
    person = ch["person.A"] > 0
    assert person.mean() > 0.1
    parts = rgb("albedo") * rgb("diffuse") + rgb("specular")
    assert np.abs(rgb("person") - parts)[person].max() <= 1e-5 * max(1.0, np.abs(parts).max())
    lights = [name for name in ch if name.startswith("light") and name.endswith(".diffuse.R")]
    assert len(lights) == 16  # --per-light: the map's 16 lights
    for name in lights:
        assert np.all(np.isfinite(ch[name])) and ch[name].min() >= 0
    vis = ch["visibility.Y"][person]
    assert vis.min() >= 0 and vis.max() <= 1 and vis.min() < 0.9  # some of her is in shadow
    assert np.all(rgb("diffuse")[person] <= rgb("unshadowed")[person] + 1e-5)


def test_a_batch_killed_and_run_again_completes(tmp_path):
    args = [PHOTO, "--env", *MAPS, "--yaw", "0", "120", "240", "-o", tmp_path / "out", "--workers", "2"]
    proc = batch(tmp_path, *args, wait=False)
    manifest = tmp_path / "out" / "manifest.jsonl"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None:
        if manifest.is_file() and '"done"' in manifest.read_text():
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    first = done_items(tmp_path / "out")
    assert 1 <= len(first) < 6
    time.sleep(1.5)  # its workers see their batch gone and end
    again = batch(tmp_path, *args)
    assert again.returncode == 0, again.stderr
    assert f"{len(first)} already done" in again.stdout
    items = done_items(tmp_path / "out")
    assert sorted(items) == sorted(set(items)) and len(items) == 6  # every item done, each once
    assert not list((tmp_path / "out").rglob("*.tmp"))


def test_a_bad_map_fails_its_own_looks(tmp_path):
    (tmp_path / "bad.hdr").write_text("not a map")
    res = batch(tmp_path, PHOTO, "--env", MAPS[0], tmp_path / "bad.hdr", tmp_path / "missing.hdr", "-o", tmp_path / "out")
    assert res.returncode == 1 and "batch: 1 done, 2 failed" in res.stdout, res.stdout + res.stderr
    lines = [l for l in res.stderr.splitlines() if l.startswith("relight: underpass/")]
    assert len(lines) == 2 and "bad.hdr: not a Radiance HDR image" in lines[0] and "missing.hdr" in lines[1]
    assert "Traceback" not in res.stderr and (tmp_path / "out" / "underpass" / "venice_sunset_256.png").is_file()
    assert (tmp_path / "out" / "contact-sheet.png").is_file()


def test_two_batches_on_one_folder(tmp_path):
    from viewer.batch.manifest import batch_lock

    with batch_lock(tmp_path / "out"):
        res = batch(tmp_path, PHOTO, "--env", MAPS[0], "-o", tmp_path / "out")
    assert res.returncode == 2 and f"is being written by another relight (process {os.getpid()}" in res.stderr
    assert res.stderr.count("\n") == 1 and not (tmp_path / "out" / "manifest.jsonl").exists()


@pytest.fixture(scope="module")
def ray_cluster():
    """A local Ray cluster (``ray start --head``, 2 CPUs) for this module's tests, stopped after them
    (a start and a stop take 10-14 s); a test that kills a worker leaves the cluster to the next."""
    from viewer.lab.bench.batch import local_ray_cluster

    with local_ray_cluster() as env:
        yield env


def test_a_ray_cluster_with_a_worker_killed_mid_batch(tmp_path, ray_cluster):
    """A photo and a clip of two frames under twelve looks: a worker is still rendering when the first
    item is done, even on a slow machine; it is killed and every item is done once."""
    from test_clips import person_frames, write_clip

    clip = write_clip(tmp_path / "walk.mp4", person_frames(2, 160, 240), audio=None)
    args = [PHOTO, clip, "--env", *MAPS, "--yaw", "0", "60", "120", "180", "240", "300", "-o", tmp_path / "out", "--ray", "auto",
            "--threads", "1"]
    proc = batch(tmp_path, *args, wait=False, env=ray_cluster)
    killed = None
    deadline = time.monotonic() + 300
    while killed is None and time.monotonic() < deadline and proc.poll() is None:
        ps = subprocess.run(["ps", "-eo", "pid,args"], capture_output=True, text=True).stdout
        running = [int(line.split()[0]) for line in ps.splitlines() if "ray::Worker.run" in line]
        if running and (tmp_path / "out" / "manifest.jsonl").is_file() and \
                '"done"' in (tmp_path / "out" / "manifest.jsonl").read_text():
            killed = running[0]
            os.kill(killed, signal.SIGKILL)
        time.sleep(0.05)
    out, err = proc.communicate(timeout=600)
    assert killed is not None, (out, err)
    assert proc.returncode == 0, err
    items = done_items(tmp_path / "out")
    assert len(items) == 24 and sorted(items) == sorted(set(items)), items
    assert "batch: 24 done, 0 failed" in out
    assert len(list((tmp_path / "out" / "walk").glob("*.mp4"))) == 12 and not list((tmp_path / "out" / "walk").glob("*.parts"))


def test_a_clip_split_over_ray_actors_with_one_killed(tmp_path, ray_cluster):
    """A clip of 44 frames on two actors: inferred in two overlapping ranges; an actor killed while
    the ranges run, its range taken up again where it stopped; the relit clip whole, its three parts
    relit by the actors and joined."""
    from test_clips import decoded

    from viewer.lab.bench.clip_memory import panning_clip

    clip = panning_clip(tmp_path / "walk.mp4", 4.4, fps=10, size=(120, 180))
    out = tmp_path / "out"
    proc = batch(tmp_path, clip, "--env", MAPS[0], "-o", out, "--ray", "auto", "--threads", "1", wait=False, env=ray_cluster)
    killed = None
    deadline = time.monotonic() + 600
    while killed is None and time.monotonic() < deadline and proc.poll() is None:
        records = list((tmp_path / "cache" / "bundles").glob("walk-clip-*/frames/*.json"))
        ps = subprocess.run(["ps", "-eo", "pid,args"], capture_output=True, text=True).stdout
        running = [int(line.split()[0]) for line in ps.splitlines() if "ray::Worker.run" in line]
        if len(records) >= 3 and len(running) == 2:
            killed = running[0]
            os.kill(killed, signal.SIGKILL)
        time.sleep(0.05)
    stdout, err = proc.communicate(timeout=900)
    assert killed is not None, (stdout, err)
    assert proc.returncode == 0 and "batch: 1 done, 0 failed" in stdout, err
    inferred = [e for e in events(out) if e["event"] == "inferred"]
    assert len(inferred) == 1 and inferred[0]["ranges"] == 2
    frames, _, _ = decoded(next((out / "walk").glob("*.mp4")))
    assert len(frames) == 44 and not list((out / "walk").glob("*.parts"))


def test_a_clip_rendered_over_ray_workers(tmp_path, ray_cluster):
    """``relight render CLIP --ray``: 44 frames at 10 a second inferred in two ranges and relit in
    three parts over two actors, joined with the source's audio; the same clip rendered by one process
    from that bundle is the same to the bit (every frame a function of its index: no seam)."""
    from test_clips import decoded, person_frames, write_clip

    there = person_frames(11, 90, 180)  # there and back, twice: the photo is only so wide
    clip = write_clip(tmp_path / "walk.mp4", 2 * (there + there[::-1]))
    common = ["--env", MAPS[0], "--max-size", "256"]
    env = {**ray_cluster, "RELIGHT_CACHE": str(tmp_path / "cache" / "lights")}
    spread = subprocess.run([sys.executable, "-m", "viewer.cli.main", "render", str(clip), *map(str, common), "-o",
                             str(tmp_path / "spread.mp4"), "--ray", "auto"], capture_output=True, text=True, env=env, timeout=900)
    assert spread.returncode == 0, spread.stderr
    assert "2 Ray workers started" in spread.stdout and "in 2 ranges over 2 workers" in spread.stdout, spread.stdout
    assert "0 kept from an earlier run" in spread.stdout and "parts kept" not in spread.stdout
    bundle = next((tmp_path / "cache" / "bundles").glob("walk-clip-*"))
    assert len(json.loads((bundle / "clip.json").read_text())["ranges"]) == 2
    one = subprocess.run([sys.executable, "-m", "viewer.cli.main", "render", str(clip), *map(str, common), "-o",
                          str(tmp_path / "one.mp4")], capture_output=True, text=True, env=env, timeout=900)
    assert one.returncode == 0 and "44 kept from an earlier run" in one.stdout, one.stderr
    frames, times, audio = decoded(tmp_path / "spread.mp4")
    alone, alone_times, _ = decoded(tmp_path / "one.mp4")
    assert len(frames) == 44 and times == alone_times and audio
    assert all(np.array_equal(a, b) for a, b in zip(frames, alone))
    assert not (tmp_path / "spread.parts").exists()


def test_ray_is_for_a_clip(tmp_path):
    res = subprocess.run([sys.executable, "-m", "viewer.cli.main", "render", str(PHOTO), "--env", str(MAPS[0]), "-o",
                          str(tmp_path / "p.png"), "--ray", "local"], capture_output=True, text=True, timeout=300)
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "--ray and --workers spread a clip's frames" in res.stderr


def test_an_idle_worker_killed_is_replaced(tmp_path):
    """A worker killed while it waits (the kernel's out-of-memory killer picks any) leaves no lock
    held: the batch goes on with a new one."""
    from viewer.batch.pools import LocalPool

    pool = LocalPool(2, 1)
    try:
        victim = pool._slots[0]["proc"]
        time.sleep(1.0)
        os.kill(victim.pid, signal.SIGKILL)
        victim.join(5)
        pool.submit({"id": 1, "kind": "infer", "photo": str(tmp_path / "missing.jpg"), "max_size": 64,
                     "bundles": str(tmp_path / "bundles")})
        got = []
        deadline = time.monotonic() + 120
        while not got and time.monotonic() < deadline:
            got = [r for r in pool.results(0.5) if r.get("id") == 1]
        assert got and not got[0]["ok"] and "missing.jpg" in got[0]["error"]  # its one line, from a live worker
        assert all(slot["proc"].is_alive() for slot in pool._slots)
    finally:
        pool.close()


def test_what_an_item_wrote_before_failing_stays_ours(tmp_path):
    from viewer.batch.manifest import Manifest, Ownership

    (tmp_path / "p").mkdir()
    png = tmp_path / "p" / "look.png"
    png.write_bytes(b"half of a batch's work")
    with Manifest(tmp_path) as m:
        m.add("start", item="p/look", outputs=["p/look.png", "p/look.exr"])
        m.add("failed", item="p/look", key="k", error="disk full",
              sha256={"p/look.png": __import__("hashlib").sha256(png.read_bytes()).hexdigest()})
    own = Ownership(Manifest(tmp_path))
    assert own.ours(tmp_path, "p/look.png")
    png.write_bytes(b"the user's file now")
    assert not Ownership(Manifest(tmp_path)).ours(tmp_path, "p/look.png")


def test_a_cut_manifest_line_is_ended(tmp_path):
    from viewer.batch.manifest import Manifest

    (tmp_path / "manifest.jsonl").write_text('{"event": "done", "item": "a", "key": "k"}\n{"event": "start", "item": "b", "outp')
    with Manifest(tmp_path) as m:
        m.add("inferred", item="photo.jpg")
    assert [e["event"] for e in Manifest(tmp_path).events] == ["done", "inferred"]


def test_look_names_never_collide(tmp_path):
    from viewer.batch.plan import look_specs

    names = [l.name for l in look_specs(["a/x.hdr", "b/x.hdr", "c/x-2.hdr", "d/x.hdr"], [], None, [], None)]
    assert len(set(names)) == 4, names


def test_the_contact_sheet_keeps_a_users_file_and_skips_what_it_cannot_read(first_run):
    from viewer.batch.contact_sheet import contact_sheet
    from viewer.batch.manifest import Manifest, Ownership

    out = first_run[2]
    manifest = Manifest(out)
    done = manifest.finished()
    broken = dict(done)
    broken["underpass/missing"] = {**next(iter(done.values())), "outputs": ["underpass/nothing.png"]}
    broken["another/venice_sunset_256"] = done["underpass/venice_sunset_256"]  # a photo with one of the looks alone
    assert contact_sheet(out, broken, Ownership(manifest)) == out / "contact-sheet.png"  # ours: made again
    (out / "contact-sheet.png").write_bytes(b"my own sheet")
    assert contact_sheet(out, done, Ownership(Manifest(out))) is None
    assert (out / "contact-sheet.png").read_bytes() == b"my own sheet"


def test_names_stay_inside_the_batch_folder_and_its_own_outputs_are_not_photos(tmp_path):
    """A photo named ``...jpg`` (stem ``..``) or ``.hidden.jpg`` and a map named ``...hdr`` write inside
    ``-o``; a batch whose ``-o`` is the folder of its photos, run twice, does not take its own contact
    sheet or outputs for photos (the second run has nothing to do)."""
    from viewer.batch.plan import collect_photos, look_specs, photo_names

    names = photo_names([Path("a/...jpg"), Path("b/.hidden.jpg"), Path("c/.jpg")])
    assert all(n and not n.startswith(".") and "/" not in n for n in names.values()) and len(set(names.values())) == 3
    assert not look_specs(["m/...hdr"], [], None, [], None)[0].name.startswith(".")
    folder = tmp_path / "shoot"
    folder.mkdir()
    shutil.copy(PHOTO, folder / "...jpg")
    for _ in range(2):
        res = batch(tmp_path, folder, "--env", MAPS[0], "-o", folder)
        assert res.returncode == 0, res.stderr
    assert not (tmp_path / "venice_sunset_256.png").exists() and (folder / "photo" / "venice_sunset_256.png").is_file()
    assert [p.name for p in collect_photos([folder])[0]] == ["...jpg"]
    assert done_items(folder) == ["photo/venice_sunset_256"]  # the second run found it done


def test_a_damaged_cached_bundle_is_inferred_again(tmp_path):
    """A file of a cached bundle cut short or deleted fails no later batch: the bundle is made again."""
    from viewer.photo.inference import cached_bundle

    bundles = tmp_path / "cache" / "bundles"
    first, cached = cached_bundle(PHOTO, max_size=256, bundles=bundles)
    assert not cached
    for damage in ("cut", "delete"):
        victim = first / "albedo.exr"
        if damage == "cut":
            victim.write_bytes(victim.read_bytes()[:100])
        else:
            victim.unlink()
        again, cached = cached_bundle(PHOTO, max_size=256, bundles=bundles)
        assert again == first and not cached and (first / "albedo.exr").stat().st_size > 1000
    assert cached_bundle(PHOTO, max_size=256, bundles=bundles)[1]
    assert sorted(p.name for p in bundles.iterdir()) == [first.name]  # nothing left beside it


def test_a_photo_swapped_while_it_is_inferred_leaves_no_bundle(tmp_path, monkeypatch):
    """The photo's bytes replaced after its key was taken and before the networks read it (issue
    43: a batch had kept the other photo's output as done): one line, and no cached bundle under the
    old key."""
    import viewer.photo.inference as inference
    from viewer.errors import InputError

    photo = tmp_path / "p.jpg"
    shutil.copy(PHOTO, photo)
    other = asset_dir() / "photos" / "street.jpg"
    other = other if other.is_file() else PHOTO
    real = inference.infer

    def swapped(photo_path, *args, **kwargs):
        from PIL import Image

        with Image.open(other) as im:
            im.transpose(Image.FLIP_LEFT_RIGHT).save(photo_path)  # other bytes, still a photo
        return real(photo_path, *args, **kwargs)

    monkeypatch.setattr(inference, "infer", swapped)
    bundles = tmp_path / "bundles"
    with pytest.raises(InputError, match="changed while it was being inferred"):
        inference.cached_bundle(photo, max_size=256, bundles=bundles)
    assert not bundles.exists() or not any(bundles.iterdir())


def test_the_automatic_yaw_turns_maps_and_leaves_the_users_own_lights(tmp_path):
    """``--yaw auto`` (the default) starts each look as ``relight render`` does: a light file of the
    user's own stays as written (its picture at auto is its picture at yaw 0, to the bit), a map and a
    light file fitted to a map turn their brightest light to the camera (another picture than at 0)."""
    from test_cli import key_light_file

    from viewer.files.imageio import read_png

    own = key_light_file(tmp_path / "key.json")
    fitted = asset_dir() / "envmaps" / "venice_sunset_256.lights.json"
    out = tmp_path / "out"
    res = batch(tmp_path, PHOTO, "--env", MAPS[1], "--lights", own, fitted, "--yaw", "auto", "0", "-o", out,
                "--workers", "1")
    assert res.returncode == 0, res.stderr
    picture = lambda look: read_png(out / "underpass" / f"{look}.png")  # noqa: E731
    np.testing.assert_array_equal(picture("key_yauto"), picture("key_y0"))
    for look in ("studio_small_03_256", "venice_sunset_256"):
        assert np.abs(picture(f"{look}_yauto") - picture(f"{look}_y0")).mean() > 0.01, look
