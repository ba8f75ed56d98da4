"""Where the models run: CUDA, Apple MPS or the CPU, in bfloat16 on a GPU and float32 on the CPU."""

from __future__ import annotations

from typing import TYPE_CHECKING

from deploy.errors import ConfigError

if TYPE_CHECKING:
    import torch


def choose_device(preference: str = "auto") -> tuple[str, torch.dtype]:
    """The torch device name and dtype for `preference` ("auto" picks cuda, then mps, then cpu)."""
    import torch

    available = {"cuda": torch.cuda.is_available(), "mps": torch.backends.mps.is_available(), "cpu": True}
    if preference == "auto":
        device = next(name for name, ok in available.items() if ok)
    elif preference not in available:
        raise ConfigError(f"unknown device {preference!r}: choose auto, cuda, mps or cpu")
    elif not available[preference]:
        raise ConfigError(
            f"device {preference!r} is not available on this machine (torch {torch.__version__}); "
            "use --device auto or cpu"
        )
    else:
        device = preference
    return device, (torch.float32 if device == "cpu" else torch.bfloat16)
