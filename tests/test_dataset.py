"""``relight dataset make``: layout, resume, shards, determinism and the loader."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from viewer.cli.main import main
from viewer.errors import InputError
from viewer.files.imageio import read_exr
from viewer.lab.data.dataset import DatasetConfig, make_sample, map_pool, sample_dir
from viewer.lab.data.loader import RelightDataset


def test_layout_and_manifests(tiny_dataset):
    dataset = tiny_dataset
    out, _ = dataset
    for i in range(3):
        d = sample_dir(DatasetConfig(out, 3), i)
        assert (d / "sample.json").is_file() and (d / "scene.json").is_file()
        full = read_exr(d / "lighting_0" / "full.exr")
        assert full.shape == (64, 64, 3) and np.isfinite(full).all() and full.max() > 0
    m0 = json.loads((out / "manifest-0of2.json").read_text())
    m1 = json.loads((out / "manifest-1of2.json").read_text())
    assert (m0["made"], m1["made"]) == (2, 1) and m0["maps"] == m1["maps"] and m0["seconds_per_sample_median"] > 0


def test_resume_skips_finished_samples(tiny_dataset, capsys):
    dataset = tiny_dataset
    out, args = dataset
    before = (sample_dir(DatasetConfig(out, 3), 0) / "sample.json").stat().st_mtime_ns
    assert main(args) == 0
    assert "0 samples made (0 relit pairs), 3 already there" in capsys.readouterr().out
    assert (sample_dir(DatasetConfig(out, 3), 0) / "sample.json").stat().st_mtime_ns == before


def test_same_seed_same_sample(tiny_dataset, tmp_path):
    dataset = tiny_dataset
    out, _ = dataset
    cfg = DatasetConfig(tmp_path, 3, res=64, spp=16, lightings=1, pool=1)
    import shutil

    shutil.copytree(out / "maps", tmp_path / "maps")  # the same pool (fitted once)
    make_sample(cfg, 1, map_pool(cfg))
    for name in ("full", "diffuse", "diffuse_shadowed"):
        a = read_exr(sample_dir(cfg, 1) / "lighting_0" / f"{name}.exr")
        b = read_exr(out / "samples" / "000001" / "lighting_0" / f"{name}.exr")
        assert np.array_equal(a, b)


def test_loader_items_and_augmentation(tiny_dataset):
    dataset = tiny_dataset
    out, _ = dataset
    plain = RelightDataset(out)
    assert len(plain) == 3
    item = plain[0]
    assert item["image"].shape == (3, 64, 64) and item["lights"].shape == (16, 7) and item["mask"].shape == (1, 64, 64)
    assert all(torch.isfinite(v).all() for v in item.values())
    aug = RelightDataset(out, augment=True, seed=1)
    for _ in range(8):  # some draw mirrors: then normals' x and lights' x flip with the image
        a = aug[0]
        mirrored = torch.allclose(a["mask"], torch.flip(item["mask"], dims=[2]))
        if mirrored and not torch.allclose(a["mask"], item["mask"]):
            assert torch.allclose(a["normal"][0], -torch.flip(item["normal"][0], dims=[1]))
            assert torch.allclose(a["lights"][:, 0], -item["lights"][:, 0])
        scale = a["lights"][:, 4:].sum() / item["lights"][:, 4:].sum()
        assert torch.allclose(a["image"].sum(), item["image"].sum() * scale, rtol=1e-3)


def test_bad_arguments(tmp_path):
    with pytest.raises(InputError):
        DatasetConfig("x", 3, shard=(2, 2))
    assert main(["dataset", "make", "--out", str(tmp_path), "--count", "1", "--shard", "a/b"]) == 2


def test_the_key_split_holds_the_same_people_under_key_lights(tiny_dataset, tmp_path):
    """``--split key``: the people of the same seed (the same G-buffers), each lit by a key-light
    map that is not turned, with the map's lights fitted; the person's images are not the map split's."""
    out, _ = tiny_dataset
    cfg = DatasetConfig(tmp_path, 3, res=64, spp=16, lightings=1, pool=2, split="key")
    record = make_sample(cfg, 1, map_pool(cfg))
    lighting = record["lightings"][0]
    assert lighting["kind"] in ("key", "key_rim") and lighting["yaw"] == 0.0 and lighting["map"].startswith("key_0_")
    for name in ("normal", "depth", "albedo"):
        assert np.array_equal(read_exr(sample_dir(cfg, 1) / f"{name}.exr"), read_exr(out / "samples" / "000001" / f"{name}.exr"))
    full = read_exr(sample_dir(cfg, 1) / "lighting_0" / "full.exr")
    assert np.isfinite(full).all() and full.max() > 0
    assert not np.array_equal(full, read_exr(out / "samples" / "000001" / "lighting_0" / "full.exr"))
    lights = json.loads((sample_dir(cfg, 1) / "lighting_0" / "lights.json").read_text())["lights"]
    assert len(lights) >= 1
