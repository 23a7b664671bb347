"""The networks: U-Net shapes, the depth losses, and training / resuming / loading on a real (tiny) dataset."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from viewer.cli.main import main
from viewer.errors import InputError
from viewer.nets import depth as dn, inverse as inv
from viewer.nets.photo import photo_input
from viewer.nets.unet import UNet
from viewer.nets.weights import load_network


def test_unet_outputs():
    net = UNet(4, {"a": 3, "b": 1}, width=8, levels=3)
    out = net(torch.zeros(2, 4, 32, 48))
    assert out["a"].shape == (2, 3, 32, 48) and out["b"].shape == (2, 1, 32, 48)
    with pytest.raises(ValueError):
        net(torch.zeros(1, 4, 30, 32))


def test_depth_loss_ignores_distance_and_gaps():
    g = torch.Generator().manual_seed(0)
    target = 0.5 + 0.05 * torch.rand(1, 1, 16, 16, generator=g)
    mask = torch.ones(1, 1, 16, 16)
    mask[..., :3] = 0
    shifted = target + 0.2  # the same shape further away: no loss
    loss = dn.depth_loss(shifted, target, mask)
    assert loss["total"].item() < 1e-6
    bumped = target.clone()
    bumped[..., 8:, :] += 0.1  # a step the target does not have: both terms see it
    loss = dn.depth_loss(bumped, target, mask)
    assert float(loss["l1"]) > 0.01 and float(loss["slope"]) > 0
    # a depth gap in the target is left out of the slope term
    gap_target = target.clone()
    gap_target[..., 8:, :] += 0.5
    assert float(dn.depth_loss(gap_target, gap_target, mask)["slope"]) == 0.0


def test_metric_depth_inverts_the_normalization():
    depth = 4.2 + 0.3 * torch.rand(1, 1, 8, 8)
    mask = torch.ones(1, 1, 8, 8)
    t = dn.depth_target(depth, mask)
    back = dn.metric_depth(t, mask, float(dn.masked_median(depth, mask)))
    assert torch.allclose(back, depth, atol=1e-5)


def test_depth_network_can_fit_one_person(tiny_dataset):
    """A small U-Net fits one example: the loss falls well below a flat figure's."""
    from viewer.lab.data.loader import RelightDataset

    item = RelightDataset(tiny_dataset[0])[0]
    batch = {k: v[None] for k, v in item.items()}
    torch.manual_seed(0)
    net = UNet(4, {"depth": 1}, width=8, levels=3)
    opt = torch.optim.Adam(net.parameters(), lr=5e-3, betas=(0.5, 0.999))
    x, _ = photo_input(batch["image"], batch["mask"], background=False)
    target = dn.depth_target(batch["depth"], batch["mask"])
    m = batch["mask"] > 0.5
    flat = float((target - dn.masked_median(target, batch["mask"])).abs()[m].mean())
    for _ in range(150):
        loss = dn.depth_loss(torch.sigmoid(net(x)["depth"]), target, batch["mask"])
        opt.zero_grad()
        loss["total"].backward()
        opt.step()
    assert loss["l1"].item() < 0.5 * flat


def test_train_resume_and_load(tiny_dataset, tmp_path, capsys):
    data, _ = tiny_dataset
    args = ["train", "depth", "--data", str(data), "--out", str(tmp_path), "--res", "64", "--levels", "3", "--width", "8",
            "--batch", "2"]
    assert main(args + ["--epochs", "2"]) == 0
    assert "depth: 2 epochs" in capsys.readouterr().out
    card = json.loads((tmp_path / "depth.json").read_text())
    first = card["history"]
    assert len(first) == 2 and card["val_items"] == 1 and card["train_items"] == 2  # person 0 validates
    assert (tmp_path / "depth_loss.png").stat().st_size > 0 and (tmp_path / "depth.checkpoint.pt").is_file()
    # resume: two finished epochs are kept, a third is added
    assert main(args + ["--epochs", "3"]) == 0
    history = json.loads((tmp_path / "depth.json").read_text())["history"]
    assert len(history) == 3 and history[:2] == first
    net = load_network(tmp_path / "depth.safetensors")
    out = net(torch.zeros(1, 4, 64, 64))["depth"]
    assert out.shape == (1, 1, 64, 64) and torch.isfinite(out).all()
    # a different network size in the same folder is refused with a clear error
    assert main(args[:-4] + ["--width", "16", "--batch", "2", "--epochs", "4"]) == 2
    # fine-tuning: a fresh run starts from these weights (its first validation is the last one's), and
    # weights of another size are refused in one line
    start = str(tmp_path / "depth.safetensors")
    base = ["train", "depth", "--data", str(data), "--res", "64", "--levels", "3", "--batch", "2", "--epochs", "1", "--init", start]
    assert main(base + ["--out", str(tmp_path / "tuned"), "--width", "8", "--lr", "1e-12"]) == 0
    card = json.loads((tmp_path / "tuned" / "depth.json").read_text())
    assert card["init"] == start
    assert [st["epochs"] for st in card["lineage"]] == [3] and card["lineage"][0]["weights"] == start
    # the model card adds the stages up
    import importlib.util

    spec = importlib.util.spec_from_file_location("ship_networks", Path(__file__).parents[1] / "tools" / "ship_networks.py")
    ship = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ship)
    shipped = {net: json.loads((ship.ROOT / "assets" / "networks" / f"{net}.json").read_text()) for net in ship.NETWORKS}
    text = ship.model_card({**shipped, "depth": card}, 20.0, None)
    assert "| 1 (after 3) |" in text and "depth: 3 epochs on 2 pairs" in text
    assert card["history"][0]["val"] == pytest.approx(history[-1]["val"], rel=1e-4)
    # the stages are read when the run starts: weights replaced later (shipping) do not change them
    replaced = json.loads((tmp_path / "depth.json").read_text())
    (tmp_path / "depth.json").write_text(json.dumps({**replaced, "epochs_done": 99, "init": None}))
    assert main(base[:-4] + ["--epochs", "2", "--init", start, "--out", str(tmp_path / "tuned"), "--width", "8", "--lr", "1e-12"]) == 0
    assert [st["epochs"] for st in json.loads((tmp_path / "tuned" / "depth.json").read_text())["lineage"]] == [3]
    (tmp_path / "depth.json").write_text(json.dumps(replaced))
    capsys.readouterr()
    assert main(base + ["--out", str(tmp_path / "other"), "--width", "16"]) == 2
    assert "another network" in capsys.readouterr().err



def test_the_silhouette_prior_is_trained_recorded_and_read(tiny_dataset, tmp_path):
    data, _ = tiny_dataset
    assert main(["train", "depth", "--data", str(data), "--out", str(tmp_path), "--res", "64", "--levels", "3",
                 "--width", "8", "--batch", "2", "--epochs", "1", "--silhouette"]) == 0
    card = json.loads((tmp_path / "depth.json").read_text())
    assert card["model"]["in_channels"] == 7 and card["model"]["inputs"] == ["photo", "mask", "silhouette"]
    net = load_network(tmp_path / "depth.safetensors")
    photo, mask = torch.rand(1, 3, 64, 64), torch.zeros(1, 1, 64, 64)
    mask[..., 8:56, 20:44] = 1.0
    depth = dn.predict(net, photo, mask, 4.0)  # the prediction builds the seven channels the card names
    assert depth.shape == (1, 1, 64, 64) and torch.isfinite(depth).all()
    # a card whose inputs do not add up to its channels is refused in one line
    card["model"]["inputs"] = ["photo", "mask"]
    (tmp_path / "depth.json").write_text(json.dumps(card))
    with pytest.raises(InputError, match="inputs"):
        load_network(tmp_path / "depth.safetensors")


def test_the_body_prior_experiment_trains_and_the_product_refuses_its_weights(tiny_dataset, tmp_path):
    """The lab's body-prior experiment (lab/data/body_prior.py): the prior is made once per sample,
    lines up with the person, trains, and weights that read it are refused by the product (which
    has no body fit) in one line."""
    import shutil

    import numpy as np

    from viewer.lab.data.loader import RelightDataset, body_channels
    from viewer.scene.bundle import load_scene

    data = tmp_path / "data"  # a copy: the priors are written into the samples
    shutil.copytree(tiny_dataset[0], data)
    sample = sorted((data / "samples").iterdir())[0]
    body = body_channels(sample, 64)
    assert (sample / "body_prior.npz").is_file() and np.array_equal(body, body_channels(sample, 64))  # made once, read back
    person = load_scene(sample).mask
    prior = body[..., 4] > 0.5
    assert (person & prior).sum() / (person | prior).sum() > 0.4  # the same person, give or take the pose noise
    assert np.allclose(np.linalg.norm(body[..., :3][prior], axis=-1), 1.0, atol=2e-3)
    mirrored = RelightDataset(data, augment=True, seed=3, fields=("image", "mask", "body"))
    assert all(torch.isfinite(mirrored[i]["body"]).all() for i in range(2))
    out = tmp_path / "net"
    assert main(["train", "depth", "--data", str(data), "--out", str(out), "--res", "64", "--levels", "3",
                 "--width", "8", "--batch", "2", "--epochs", "1", "--body-prior"]) == 0
    card = json.loads((out / "depth.json").read_text())
    assert card["model"]["in_channels"] == 9 and card["model"]["inputs"] == ["photo", "mask", "body"]
    with pytest.raises(InputError, match="inputs"):
        load_network(out / "depth.safetensors")


class _RunsCode:
    """What a crafted checkpoint holds: unpickling it would run a command."""

    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        import os

        return (os.system, (f"touch {self.marker}",))


def test_a_crafted_checkpoint_is_refused_without_running_it(tiny_dataset, tmp_path, capsys):
    data, _ = tiny_dataset
    marker = tmp_path / "code-ran"
    torch.save({"config": {"task": "depth"}, "payload": _RunsCode(marker)}, tmp_path / "depth.checkpoint.pt")
    args = ["train", "depth", "--data", str(data), "--out", str(tmp_path), "--res", "64", "--levels", "3", "--width", "8",
            "--batch", "2", "--epochs", "1"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "depth.checkpoint.pt: refused: not a plain checkpoint" in err and err.count("\n") == 1
    assert not marker.exists() and not (tmp_path / "depth.safetensors").exists()
    (tmp_path / "depth.checkpoint.pt").write_bytes(b"PK\x03\x04 truncated")
    assert main(args) == 2
    assert "not a readable checkpoint" in capsys.readouterr().err

def _logit(p):
    p = p.clamp(1e-4, 1 - 1e-4)
    return torch.log(p / (1 - p))


def _perfect_outputs(batch, lights):
    """Network outputs that decode to the true maps and the given (N, 7) lights."""
    material = torch.cat([batch["albedo"], batch["specular"], batch["roughness"]], dim=1)
    anchor = torch.as_tensor(inv.fibonacci_sphere(len(lights)), dtype=torch.float32)
    raw = torch.cat([lights[:, :3] - anchor, torch.logit(lights[:, 3:4] / inv.SIGMA_MAX, eps=1e-4),
                     lights[:, 4:7] + torch.log(-torch.expm1(-lights[:, 4:7]))], dim=1)  # softplus^-1
    return {"normal": batch["normal"], "material": _logit(material), "lights": raw.reshape(1, -1)}


def test_inverse_losses_agree_with_the_ray_traced_data(tiny_dataset):
    """The loss conventions against the dataset: the true maps score zero on texture, and the map's
    fitted lights explain the ray-traced shading far better than the same lights pointing elsewhere."""
    from viewer.lab.data.loader import RelightDataset

    item = RelightDataset(tiny_dataset[0])[0]
    batch = {k: v[None] for k, v in item.items()}
    photo = batch["image"] + (1 - batch["mask"]) * batch["background"]
    _, scale = photo_input(photo, batch["mask"])
    lights = batch["lights"][0].clone()
    lights[:, 4:7] *= scale.reshape(())
    right = inv.inverse_loss(_perfect_outputs(batch, lights), batch, scale, sigma_items=1)
    assert right["albedo"] < 1e-3 and right["normal"] < 1e-3 and right["normal_degrees"] < 1.0
    wrong_lights = lights.clone()
    wrong_lights[:, :3] = -wrong_lights[:, :3]
    wrong = inv.inverse_loss(_perfect_outputs(batch, wrong_lights), batch, scale, sigma_items=1)
    for term in ("diffuse_shading", "full_recon", "sigma"):
        assert right[term] < 0.35 * wrong[term], (term, float(right[term]), float(wrong[term]))
    assert torch.isfinite(right["total"]) and right["total"] < wrong["total"]


def test_light_tensors_are_valid_for_any_raw_output():
    raw = torch.randn(3, 7 * 16) * 50
    raw[0] = 0
    d, s, i = inv.light_tensors(raw)
    assert torch.allclose(d.norm(dim=-1), torch.ones(3, 16), atol=1e-5)
    assert (s >= 0).all() and (s <= inv.SIGMA_MAX).all() and (i >= 0).all() and torch.isfinite(i).all()


def test_laplacian_loss_sees_structure_not_only_values():
    g = torch.Generator().manual_seed(1)
    a = torch.rand(1, 3, 32, 32, generator=g)
    mask = torch.ones(1, 1, 32, 32)
    assert inv.laplacian_l1(a, a, mask) == 0
    blurred = torch.nn.functional.avg_pool2d(a, 3, 1, 1)
    assert inv.laplacian_l1(blurred, a, mask) > 0.02  # detail lost
    assert inv.laplacian_l1(a + 0.1, a, mask) < 0.2 * inv.laplacian_l1(blurred, a, mask)  # a flat offset barely counts


def test_held_out_evaluation_harness(tiny_dataset, tiny_networks, tmp_path):
    from viewer.lab.bench.networks import run_networks_benchmark, table

    result = run_networks_benchmark(tiny_dataset[0], tiny_networks, output=tmp_path / "b.json", figure=tmp_path / "f.png")
    m = result["metrics"]
    assert result["pairs"] == 3 and (tmp_path / "b.json").is_file() and (tmp_path / "f.png").stat().st_size > 0
    for name in ("albedo", "normal", "shading_SM", "shading_refined", "relit_refined", "relit_SH_baseline", "relit_true_maps_refined"):
        assert 0 <= m[name]["rmse"]["mean"] < 10 and -1 <= m[name]["ssim"]["mean"] <= 1, name
    assert 0 <= m["relit_refined"]["flip"]["mean"] <= 1
    # the true maps through the renderer beat one-epoch networks
    assert m["relit_true_maps_refined"]["rmse"]["mean"] < m["relit_refined"]["rmse"]["mean"]
    assert "Relit image" in table(result)
    per_pair = result["per_pair"]  # each pair's relit RMSE, ours and the baseline's
    assert len(per_pair) == 3 and np.mean([p["relit_refined"] for p in per_pair]) == pytest.approx(m["relit_refined"]["rmse"]["mean"])
    assert np.mean([p["relit_SH"] for p in per_pair]) == pytest.approx(m["relit_SH_baseline"]["rmse"]["mean"])
    assert f"on {sum(p['relit_refined'] < p['relit_SH'] for p in per_pair)} of 3 pairs" in table(result)
    # the photo's own lights, fitted to the photo, explain its shading better than the one-epoch network's guess
    own = m["own_lights"]
    assert 0 <= own["fitted_rmse_rel_scaled"]["mean"] <= own["fitted_rmse_rel"]["mean"] + 1e-9
    assert own["fitted_rmse_rel"]["mean"] < own["network_rmse_rel"]["mean"]
    # and the same fit on the true maps (its floor) does better still
    assert own["fitted_true_maps_rmse_rel"]["mean"] < own["fitted_rmse_rel"]["mean"]
    assert 0 <= m["albedo_chroma"]["chroma_l1"]["mean"] < 2 and "own lights" in table(result)


def test_torchrun_trains_one_model_in_two_processes(tiny_dataset, tmp_path):
    """Multi-process training is torch's own: torchrun + DistributedDataParallel (gloo on CPU)."""
    import socket
    import subprocess
    import sys
    from pathlib import Path

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    relight = Path(sys.executable).with_name("relight")
    res = subprocess.run([str(Path(sys.executable).with_name("torchrun")), "--nproc_per_node", "2", "--master_port", str(port),
                          str(relight), "train", "depth", "--data", str(tiny_dataset[0]), "--out", str(tmp_path), "--res", "64",
                          "--levels", "3", "--width", "8", "--batch", "1", "--epochs", "1"], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    card = json.loads((tmp_path / "depth.json").read_text())
    assert card["processes"] == 2 and card["epochs_done"] == 1 and card["train_items"] == 2
    assert load_network(tmp_path / "depth.safetensors") is not None


def test_the_chroma_loss_sees_colour_not_brightness():
    """An albedo half as bright has no chroma loss (the L1 has); a washed-out one has."""
    import numpy as np

    from viewer.lab.bench.metrics import chroma
    from viewer.nets.inverse import chroma_l1, masked_l1

    torch.manual_seed(0)
    target = torch.rand(2, 3, 16, 16) * torch.tensor([0.9, 0.2, 0.6]).view(1, 3, 1, 1) + 0.05
    mask = torch.ones(2, 1, 16, 16)
    grey = target.mean(dim=1, keepdim=True).expand_as(target)
    washed = 0.3 * target + 0.7 * grey
    assert chroma_l1(0.5 * target, target, mask).item() < 1e-6 < masked_l1(0.5 * target, target, mask).item()
    assert chroma_l1(washed, target, mask).item() > 0.05
    hwc = lambda t: t[0].permute(1, 2, 0).numpy()  # noqa: E731
    c = chroma(hwc(washed), hwc(target), np.ones((16, 16), bool))
    assert c["chroma_l1"] > 0.05 and c["saturation_pred"] < 0.5 * c["saturation_true"]
    assert chroma(hwc(target) * 2, hwc(target), np.ones((16, 16), bool))["chroma_l1"] < 1e-9


def test_a_network_reading_the_silhouette_corrects_the_prior_normal():
    """With the silhouette prior the normal decoder adds a correction to the inflation's normal:
    a decoder that outputs zero gives the prior itself, exact at the outline."""
    from viewer.nets.photo import photo_input
    from viewer.nets.silhouette import silhouette_maps

    net = UNet(7, inv.OUTPUTS, width=8, levels=3, vectors=inv.vectors(), inputs=["photo", "mask", "silhouette"])
    with torch.no_grad():
        head = net.decoders["normal"].head
        head.weight.zero_()
        head.bias.zero_()
    mask = torch.zeros(1, 1, 64, 64)
    mask[..., 10:54, 20:44] = 1.0
    maps, _, _ = inv.predict(net, torch.rand(1, 3, 64, 64), mask)
    prior = torch.from_numpy(silhouette_maps(mask[0, 0].numpy() > 0.5)).permute(2, 0, 1)
    inside = mask[0, 0] > 0.5
    assert torch.allclose(maps["normal"][0, :2][:, inside], prior[:2][:, inside], atol=1e-5)
    x, _ = photo_input(torch.rand(1, 3, 64, 64), mask, silhouette=True)
    assert torch.allclose(inv.prior_normal(x).norm(dim=1), torch.ones(1, 64, 64), atol=1e-5)
