"""Where the networks run: the one place a compute device is chosen (``--device auto|cpu|cuda``).

A new kind of device (another torch backend) is added here: its name in ``DEVICES`` and its check
in :func:`compute_device`; every command's ``--device`` and every worker's task take it from here."""

from __future__ import annotations

from viewer.errors import InputError

DEVICES = ("auto", "cpu", "cuda")  # cuda:N names one GPU of several
DEFAULT_DEVICE = "auto"  # CUDA where torch has it, else the CPU


def compute_device(name: str = DEFAULT_DEVICE) -> str:
    """``name`` (``auto``, ``cpu``, ``cuda``, ``cuda:N``) as torch names it, when this machine has it
    (``auto``: CUDA when torch has it, else the CPU); else one line naming the device (the weights
    file was blamed for a missing CUDA before)."""
    import torch

    if name == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    try:
        dev = torch.device(name)
    except (RuntimeError, TypeError) as exc:
        raise InputError(None, f"--device {name!r} is not a device torch knows ({exc}); use {', '.join(DEVICES)}") from None
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise InputError(None, f"--device {name}: this machine has no CUDA device (torch {torch.__version__}); "
                               "use --device cpu")
    if dev.type not in DEVICES:
        raise InputError(None, f"--device {name}: the networks run on cpu or cuda")
    return name
