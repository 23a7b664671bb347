"""Loading the shipped networks: weights from safetensors (never a pickle), the architecture from
the JSON card beside them. Part of the product (inference and the refined shadow mode); training
(:mod:`viewer.lab.train`) writes what this reads."""

from __future__ import annotations

from pathlib import Path

from ..errors import InputError
from ..imageio import read_json
from .unet import UNet


def load_network(path, device="cpu") -> UNet:
    """A shipped network from its safetensors file and the JSON card beside it."""
    from safetensors.torch import load_file

    path = Path(path)
    card_path = path.with_suffix(".json")
    if not path.is_file() or not card_path.is_file():
        raise InputError(path, "network weights not found (a .safetensors file with its .json card)")
    try:
        cfg = read_json(card_path, "network card")["model"]
        model = UNet(cfg["in_channels"], cfg["outputs"], cfg["width"], cfg["levels"], cfg.get("vectors"))
    except (ValueError, KeyError, TypeError) as exc:
        raise InputError(card_path, f"not a network card this program reads ({type(exc).__name__}: {exc})") from None
    try:
        model.load_state_dict(load_file(str(path), device=str(device)))
    except Exception as exc:  # a truncated file, other shapes than the card says
        raise InputError(path, f"cannot load these weights ({type(exc).__name__}: {str(exc).splitlines()[0]})") from None
    return model.eval().to(device)
