"""Loading the shipped networks: weights from safetensors (never a pickle), the architecture from
the JSON card beside them. Part of the product (inference and the refined shadow mode); training
(:mod:`viewer.lab.train`) writes what this reads."""

from __future__ import annotations

from pathlib import Path

from ..errors import InputError
from ..imageio import read_json
from .photo import INPUTS, in_channels
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
        sizes = [cfg["in_channels"], cfg["width"], *dict(cfg["outputs"]).values(), *dict(cfg.get("vectors") or {}).values()]
        if not all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= 4096 for v in sizes) \
                or not (isinstance(cfg["levels"], int) and 1 <= cfg["levels"] <= 8) or cfg["width"] > 256:
            raise ValueError("sizes out of range (channels and outputs 1-4096, width 1-256, levels 1-8)")
        inputs = cfg.get("inputs")
        known = [list(INPUTS[:n]) for n in range(2, len(INPUTS) + 1)]  # photo and mask, then the priors, in order
        if inputs is not None and (inputs not in known or in_channels(inputs) != cfg["in_channels"]):
            raise ValueError(f"inputs {inputs!r} are not one of {' or '.join(map(str, known))} adding up to "
                             f"{cfg['in_channels']} channels")
        model = UNet(cfg["in_channels"], cfg["outputs"], cfg["width"], cfg["levels"], cfg.get("vectors"), inputs)
    except (ValueError, KeyError, TypeError, AttributeError, RuntimeError, IndexError) as exc:
        raise InputError(card_path, f"not a network card this program reads ({type(exc).__name__}: {exc})") from None
    try:
        model.load_state_dict(load_file(str(path), device=str(device)))
    except Exception as exc:  # a truncated file, other shapes than the card says
        raise InputError(path, f"cannot load these weights ({type(exc).__name__}: {str(exc).splitlines()[0]})") from None
    return model.eval().to(device)
