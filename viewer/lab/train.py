"""``relight train``: training loops with checkpoints, resume, loss curves and shipped weights.

One loop for every network (:data:`TASKS` says how each reads a batch and scores it). Adam with
the paper's betas (0.5, 0.999) and a learning rate cosine-annealed to ``lr_min`` over the run;
the people of the dataset are split into training and validation (by sample, so one person's
lightings never straddle the split). Several processes (torchrun) train one model with torch's
DistributedDataParallel. After every epoch: a checkpoint (written atomically, so an
interrupted run resumes from the last finished epoch), the loss curves as a PNG, and the weights as
safetensors with a JSON card (configuration, losses, time).
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from torch.nn import functional as F

from viewer.errors import InputError
from viewer.files.imageio import atomic_path, read_json, write_text
from viewer.lab.data.loader import FIELDS
from viewer.nets import depth as depth_net, inverse as inverse_net, refine as refine_net
from viewer.nets.photo import exposure_scale, in_channels, photo_input
from viewer.nets.unet import UNet

BODY_CHANNELS = 5  # the body prior's normal, depth and mask (viewer.lab.data.loader.body_channels)


@dataclass
class TrainConfig:
    task: str
    data: Path | list[Path]
    out: Path
    res: int = 256
    epochs: int = 20
    batch: int = 4
    lr: float = 1e-3
    lr_min: float = 1e-5
    width: int = 16
    levels: int = 5
    device: str = "cpu"
    seed: int = 0
    perceptual_weight: float = inverse_net.PERCEPTUAL_WEIGHT  # inverse: the Laplacian-pyramid loss's weight
    silhouette: bool = False  # inverse and depth: the mask's silhouette prior as extra input channels
    body_prior: bool = False  # inverse and depth: the dataset's body prior (lab/data/body_prior.py) as input channels
    val_every: int = 10  # every tenth person is a validation person
    init: Path | None = None  # start from these weights (a .safetensors with its card) instead of at random

    def __post_init__(self):
        if self.task not in TASKS:
            raise InputError(None, f"unknown network {self.task!r}; one of {', '.join(TASKS)}")
        if self.task == "refine" and (self.silhouette or self.body_prior):
            raise InputError(None, "--silhouette and --body-prior are for the inverse and depth networks, not refine")
        if self.epochs < 1 or self.batch < 1 or not self.lr > 0 or self.res % 2 ** (self.levels - 1):
            raise InputError(None, f"epochs and batch must be >= 1, lr > 0, and --res a multiple of {2 ** (self.levels - 1)}")


def _resize(batch: dict, res: int) -> dict:
    out = {}
    for key, value in batch.items():
        if value.ndim == 4 and value.shape[-1] != res:
            mode = "nearest" if key in ("mask", "depth", "normal", "hard", "body") else "area"
            out[key] = F.interpolate(value, size=(res, res), mode=mode)
        else:
            out[key] = value
    return out


class Task:
    """How one network is built and scored: its U-Net outputs (image decoders and bottleneck
    vectors), input channels, the dataset images it reads (None: all), the visibility cache it
    needs (shadow-map texels, or None), and ``loss(model, batch)`` -> dict with ``total``."""

    name: str
    outputs: dict
    vectors: dict = {}
    inputs: tuple | None = ("photo", "mask")  # None: the task's own input (refinement)
    in_channels = 4
    fields: tuple | None = None
    visibility: int | None = None

    def __init__(self, cfg: TrainConfig):
        self.cfg = cfg
        if self.inputs is not None and cfg.silhouette:
            self.inputs = (*self.inputs, "silhouette")
            self.in_channels = in_channels(self.inputs)
        if self.inputs is not None and cfg.body_prior:
            # an experiment of the lab (what a fitted body would give): the product has no body
            # fit, so it refuses weights that read one (viewer.nets.weights)
            self.inputs = (*self.inputs, "body")
            self.in_channels += BODY_CHANNELS
            self.fields = (*(self.fields or FIELDS), "body")

    def network_input(self, x: torch.Tensor, batch: dict) -> torch.Tensor:
        return torch.cat([x, batch["body"]], dim=1) if self.cfg.body_prior else x


class DepthTask(Task):
    name = "depth"
    outputs = {"depth": 1}
    fields = ("image", "mask", "depth")

    def loss(self, model, batch) -> dict:
        x, _ = photo_input(batch["image"], batch["mask"], background=False, silhouette=self.cfg.silhouette)
        pred = torch.sigmoid(model(self.network_input(x, batch))["depth"])
        target = depth_net.depth_target(batch["depth"], batch["mask"])
        losses = depth_net.depth_loss(pred, target, batch["mask"])
        losses["metres"] = losses["l1"].detach() * depth_net.DEPTH_RANGE  # median-aligned L1, metres
        # the same error of a flat figure (every pixel at the median depth): the bar to clear
        m = batch["mask"] > 0.5
        flat = (target - depth_net.masked_median(target, batch["mask"])).abs()[m].mean()
        losses["flat_metres"] = flat.detach() * depth_net.DEPTH_RANGE
        return losses


class InverseTask(Task):
    """The inverse-rendering network on the photo with its background (:mod:`.inverse`)."""

    name = "inverse"
    outputs = inverse_net.OUTPUTS
    vectors = inverse_net.vectors()

    def loss(self, model, batch) -> dict:
        photo = batch["image"] + (1.0 - batch["mask"]) * batch["background"]
        x, scale = photo_input(photo, batch["mask"], silhouette=self.cfg.silhouette)
        losses = inverse_net.inverse_loss(model(self.network_input(x, batch)), batch, scale, self.cfg.perceptual_weight,
                                          sigma_items=1 if model.training else 0,
                                          base_normal=inverse_net.prior_normal(x) if self.cfg.silhouette else None)
        return losses


class RefineTask(Task):
    """The shadow refinement network on the GL engine's visibility of the true depth (:mod:`.refine`)."""

    name = "refine"
    outputs = refine_net.OUTPUTS
    inputs = None
    in_channels = refine_net.IN_CHANNELS
    visibility = refine_net.SHADOW_RESOLUTION
    fields = ("image", "mask", "normal", "depth", "diffuse_shadowed")

    def loss(self, model, batch) -> dict:
        return refine_net.refine_loss(model, batch, exposure_scale(batch["image"], batch["mask"]))


TASKS = {"depth": DepthTask, "inverse": InverseTask, "refine": RefineTask}


def _split(dataset, val_every: int):
    people = sorted({sample for sample, _ in dataset.items})
    val_people = set(people[::val_every]) if len(people) > 1 else set()
    train = [i for i, (s, _) in enumerate(dataset.items) if s not in val_people]
    val = [i for i, (s, _) in enumerate(dataset.items) if s in val_people]
    return train, val


def _data_text(data) -> str | list[str]:
    return [str(d) for d in data] if isinstance(data, (list, tuple)) else str(data)


def _atomic_save(obj, path: Path):
    tmp = path.with_name(f".{path.name}.tmp")
    torch.save(obj, tmp)
    os.replace(tmp, path)


def _plot(history: list[dict], path: Path, task: str):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    epochs = [h["epoch"] for h in history]
    fig, ax = plt.subplots(figsize=(6, 3.5), dpi=100)
    ax.plot(epochs, [h["train"] for h in history], label="training")
    if any(h.get("val") is not None for h in history):
        ax.plot(epochs, [h.get("val") for h in history], label="validation")
    ax.set_xlabel("epoch")
    ax.set_ylabel("loss")
    ax.set_yscale("log")
    ax.set_title(f"{task} network")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)


def _distributed(device: torch.device) -> tuple[int, int, torch.device]:
    """(rank, world size, device) under torchrun (``WORLD_SIZE`` > 1: one process per GPU, or per
    CPU process group with gloo); (0, 1, device) otherwise."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world <= 1:
        return 0, 1, device
    import torch.distributed as dist

    if device.type == "cuda":
        device = torch.device("cuda", int(os.environ.get("LOCAL_RANK", "0")))
        torch.cuda.set_device(device)
    if not dist.is_initialized():
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")
    return dist.get_rank(), world, device


CHECKPOINT_KEYS = ("config", "model_config", "model", "optimizer", "scheduler", "history", "epoch", "seconds")


def training_stage(card: dict, weights=None) -> dict:
    """What a model card (``<net>.json``) says of the run that made its weights: data, pairs,
    epochs, learning rate and time."""
    return {"weights": None if weights is None else str(weights), "data": card.get("data"), "train_items": card.get("train_items"),
            "epochs": card.get("epochs_done", card.get("epochs")), "lr": card.get("lr"), "seconds": card.get("seconds")}


def lineage(weights: Path, depth: int = 0) -> list[dict]:
    """The training stages behind ``weights``, newest first, read from the card beside each: the
    card's own run, then the weights it was fine-tuned from (``init``), and so on. A card missing on
    the way ends the list (its weights were made elsewhere)."""
    card_path = Path(weights).with_suffix(".json")
    if depth > 16 or not card_path.is_file():
        return []
    card = read_json(card_path, "network card")
    if "lineage" in card:  # written at training time: already complete
        return [training_stage(card, weights), *card["lineage"]]
    return [training_stage(card, weights), *(lineage(Path(card["init"]), depth + 1) if card.get("init") else [])]


def _warm_start(model, path: Path, device):
    """Fine-tuning: the weights of ``path`` (shipped or trained before) copied into ``model``, which
    must have the same architecture and inputs."""
    from viewer.nets.weights import load_network

    start = load_network(path, device)
    if start.config != model.config:
        raise InputError(path, f"--init weights are another network ({start.config}) than the one asked for ({model.config})")
    model.load_state_dict(start.state_dict())


def load_checkpoint(path: Path, device) -> dict:
    """A training checkpoint, loaded with ``weights_only=True``: tensors and plain data only, so a
    crafted file cannot run code (it is refused with one line, as is a truncated or foreign one)."""
    import pickle

    try:
        ckpt = torch.load(path, map_location=device, weights_only=True)
    except pickle.UnpicklingError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(path, f"refused: not a plain checkpoint (loading it would run code or build objects: {first[:120]})") from None
    except (RuntimeError, EOFError, OSError, ValueError) as exc:
        raise InputError(path, f"not a readable checkpoint ({type(exc).__name__}); move it away to start afresh") from None
    if not isinstance(ckpt, dict) or not all(k in ckpt for k in CHECKPOINT_KEYS):
        raise InputError(path, "not a checkpoint of relight train (keys missing); move it away to start afresh")
    return ckpt


def train(cfg: TrainConfig, progress=None) -> dict:
    """Train (or resume) ``cfg.task`` on ``cfg.data``; returns the card written beside the weights.

    Under ``torchrun --nproc_per_node K relight train ...`` the model is wrapped in torch's
    DistributedDataParallel and each process takes 1 / K of every epoch (``--batch`` per process);
    rank 0 validates and writes the checkpoint, curves and weights."""
    from viewer.lab.data.loader import RelightDataset

    torch.manual_seed(cfg.seed)
    device = torch.device(cfg.device)
    if device.type == "cuda" and not torch.cuda.is_available():
        raise InputError(None, "--device cuda asked for, but torch sees no CUDA device")
    rank, world, device = _distributed(device)
    task = TASKS[cfg.task](cfg)
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    visibility = task.visibility
    data = RelightDataset(cfg.data, augment=True, seed=cfg.seed + rank, visibility=visibility, fields=task.fields)
    val_data = RelightDataset(cfg.data, augment=False, visibility=visibility, fields=task.fields)
    train_idx, val_idx = _split(data, cfg.val_every)
    subset = torch.utils.data.Subset(data, train_idx)
    sampler = (torch.utils.data.distributed.DistributedSampler(subset, world, rank, shuffle=True, seed=cfg.seed, drop_last=True)
               if world > 1 else None)
    loader = torch.utils.data.DataLoader(subset, batch_size=cfg.batch, shuffle=sampler is None, sampler=sampler,
                                         drop_last=len(train_idx) > cfg.batch * world,
                                         generator=torch.Generator().manual_seed(cfg.seed))
    model = UNet(task.in_channels, task.outputs, cfg.width, cfg.levels, task.vectors,
                 # the cards name inputs beyond photo and mask
                 list(task.inputs) if task.inputs and (cfg.silhouette or cfg.body_prior) else None).to(device)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr, betas=(0.5, 0.999))
    steps = cfg.epochs * max(len(loader), 1)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=steps, eta_min=cfg.lr_min)
    ckpt_path = out / f"{cfg.task}.checkpoint.pt"
    history, start_epoch, seconds = [], 0, 0.0
    if ckpt_path.is_file():
        ckpt = load_checkpoint(ckpt_path, device)
        if ckpt["config"]["task"] != cfg.task or ckpt["model_config"] != model.config:
            raise InputError(ckpt_path, "a checkpoint of a different network or size is in the way (move it, or use another --out)")
        model.load_state_dict(ckpt["model"])
        opt.load_state_dict(ckpt["optimizer"])
        sched.load_state_dict(ckpt["scheduler"])
        history, start_epoch, seconds = ckpt["history"], ckpt["epoch"] + 1, ckpt["seconds"]
        # the stages before this run, as read when it started (checkpoints older than that key: read now)
        stages = ckpt["lineage"] if "lineage" in ckpt else lineage(Path(cfg.init)) if cfg.init is not None else []
    elif cfg.init is not None:
        _warm_start(model, Path(cfg.init), device)
        stages = lineage(Path(cfg.init))  # read once: the weights it started from may be replaced later
    else:
        stages = []
    net = model
    if world > 1:
        net = torch.nn.parallel.DistributedDataParallel(model, device_ids=[device.index] if device.type == "cuda" else None)
    card = None
    for epoch in range(start_epoch, cfg.epochs):
        t0 = time.perf_counter()
        net.train()
        if sampler is not None:
            sampler.set_epoch(epoch)
        losses = []
        for step, batch in enumerate(loader):
            batch = _resize({k: v.to(device) for k, v in batch.items()}, cfg.res)
            loss = task.loss(net, batch)
            opt.zero_grad(set_to_none=True)
            loss["total"].backward()
            opt.step()
            sched.step()
            losses.append(loss["total"].item())
            if progress is not None and rank == 0:
                progress(f"epoch {epoch + 1}/{cfg.epochs}", step + 1, len(loader))
        if rank != 0:
            continue
        val = _evaluate(model, task, val_data, val_idx, cfg, device)
        seconds += time.perf_counter() - t0
        history.append({"epoch": epoch + 1, "train": float(np.mean(losses)) if losses else None, **val,
                        "lr": sched.get_last_lr()[0], "seconds": round(seconds, 1)})
        _atomic_save({"config": {**asdict(cfg), "data": _data_text(cfg.data), "out": str(cfg.out),
                                 "init": None if cfg.init is None else str(cfg.init)}, "model_config": model.config,
                      "model": model.state_dict(), "optimizer": opt.state_dict(), "scheduler": sched.state_dict(),
                      "history": history, "epoch": epoch, "seconds": seconds, "lineage": stages}, ckpt_path)
        _plot(history, out / f"{cfg.task}_loss.png", cfg.task)
        card = _write_weights(model, cfg, out, device, world, len(train_idx), len(val_idx), seconds, history, stages)
    if world > 1:
        torch.distributed.barrier()
    if card is None and rank == 0:  # nothing left to train (a finished run resumed): the card on disk
        card = json.loads((out / f"{cfg.task}.json").read_text())
    return card


def _write_weights(model, cfg: TrainConfig, out: Path, device, world: int, n_train: int, n_val: int, seconds: float,
                   history: list, stages: list) -> dict:
    """The weights as safetensors and their JSON card (written after every epoch)."""
    from safetensors.torch import save_file

    weights = out / f"{cfg.task}.safetensors"
    tmp = weights.with_name(f".{weights.name}.tmp")
    save_file({k: v.detach().cpu().contiguous() for k, v in model.state_dict().items()}, str(tmp))
    os.replace(tmp, weights)
    card = {"network": cfg.task, "model": model.config, "parameters": sum(p.numel() for p in model.parameters()),
            "data": _data_text(cfg.data), "train_items": n_train, "val_items": n_val, "resolution": cfg.res,
            "epochs": cfg.epochs, "epochs_done": len(history), "batch": cfg.batch, "processes": world,
            "lr": [cfg.lr, cfg.lr_min], "device": str(device), "torch_threads": torch.get_num_threads(),
            "seconds": round(seconds, 1), "history": history, "weights": weights.name}
    if cfg.init is not None:
        card["init"] = str(cfg.init)
        card["lineage"] = stages  # the stages before this one, kept if those files go
    if cfg.task == "inverse":
        card["perceptual_weight"] = cfg.perceptual_weight
    write_text(out / f"{cfg.task}.json", json.dumps(card, indent=1) + "\n")
    return card


@torch.no_grad()
def _evaluate(model, task, dataset, indices, cfg, device) -> dict:
    if not indices:
        return {"val": None}
    model.eval()
    totals: dict[str, list] = {}
    for batch in torch.utils.data.DataLoader(torch.utils.data.Subset(dataset, indices), batch_size=cfg.batch):
        batch = {k: v.to(device) for k, v in batch.items()}
        loss = task.loss(model, _resize(batch, cfg.res))
        for k, v in loss.items():
            totals.setdefault(k, []).append(v.item() * len(batch["image"]))
    n = len(indices)
    return {"val": sum(totals["total"]) / n, **{f"val_{k}": sum(v) / n for k, v in totals.items() if k != "total"}}
