"""Loading the shipped networks: weights from safetensors (never a pickle), the architecture from
the JSON card beside them. Part of the product (inference and the refined shadow mode); training
(:mod:`viewer.lab.train`) writes what this reads."""

from __future__ import annotations

from pathlib import Path

from viewer.errors import InputError
from viewer.files.imageio import read_json
from viewer.nets.photo import INPUTS, in_channels
from viewer.nets.unet import UNet


def load_network(path, device="cpu") -> UNet:
    """A shipped network from its safetensors file and the JSON card beside it."""
    from safetensors.torch import load_file

    path = Path(path)
    card_path = path.with_suffix(".json")
    if not path.is_file() or not card_path.is_file():
        raise InputError(path, "network weights not found (a .safetensors file with its .json card)")
    try:
        cfg = read_json(card_path, "network card")["model"]
        sizes = [cfg["in_channels"], cfg["width"], *dict(cfg["outputs"]).values(), *dict(cfg.get("vectors") or {}).values()]
        if not all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= 4096 for v in sizes) \
                or not (isinstance(cfg["levels"], int) and 1 <= cfg["levels"] <= 8) or cfg["width"] > 256:
            raise ValueError("sizes out of range (channels and outputs 1-4096, width 1-256, levels 1-8)")
        inputs = cfg.get("inputs")
        known = [list(INPUTS[:n]) for n in range(2, len(INPUTS) + 1)]  # photo and mask, then the priors, in order
        if inputs is not None and (inputs not in known or in_channels(inputs) != cfg["in_channels"]):
            raise ValueError(f"inputs {inputs!r} are not one of {' or '.join(map(str, known))} adding up to "
                             f"{cfg['in_channels']} channels")
        import torch

        with torch.device("meta"):  # shapes only: a card may describe a network of many gigabytes
            shapes = UNet(cfg["in_channels"], cfg["outputs"], cfg["width"], cfg["levels"], cfg.get("vectors"), inputs)
    except (ValueError, KeyError, TypeError, AttributeError, RuntimeError, IndexError) as exc:
        raise InputError(card_path, f"not a network card this program reads ({type(exc).__name__}: {exc})") from None
    _check_weights_match(path, card_path, {k: tuple(v.shape) for k, v in shapes.state_dict().items()})
    model = UNet(cfg["in_channels"], cfg["outputs"], cfg["width"], cfg["levels"], cfg.get("vectors"), inputs)
    try:
        model.load_state_dict(load_file(str(path), device=str(device)))
    except Exception as exc:  # a truncated file, other shapes than the card says
        raise InputError(path, f"cannot load these weights ({type(exc).__name__}: {str(exc).splitlines()[0]})") from None
    return model.eval().to(device)


def _check_weights_match(path: Path, card_path: Path, expected: dict) -> None:
    """The card's network has the tensors the weights file holds, read from the file's header
    before anything is allocated (a card of width 256 and 8 levels described 40 GB of weights
    beside a file of 0.4 MB: building it thrashed the machine)."""
    from safetensors import safe_open

    try:
        with safe_open(str(path), framework="pt") as f:
            stored = {k: tuple(f.get_slice(k).get_shape()) for k in f.keys()}
    except Exception as exc:  # a truncated or foreign file
        raise InputError(path, f"cannot read these weights ({type(exc).__name__}: {str(exc).splitlines()[0]})") from None
    if stored != expected:
        differ = sorted(set(stored) ^ set(expected)) or [k for k in expected if stored[k] != expected[k]]
        raise InputError(card_path, f"the card describes another network than {path.name} holds "
                                    f"({len(differ)} tensor(s) differ, first {differ[0]})")
