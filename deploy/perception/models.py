"""Where the model weights are and how they load: a local directory or the Hugging Face cache, never a download.

`resolve_checkpoint` turns a directory or repo id into a local directory; `load_detector` / `load_tracker`
load it with transformers; any failure is one `ModelError` naming the model, the cause and the fetch command.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from deploy.errors import ModelError
from deploy.perception.config import DEFAULT_DETECTOR, DEFAULT_TRACKER, EDGETAM_TRACKER

Role = Literal["detector", "tracker"]
KNOWN_MODELS: tuple[tuple[Role, str], ...] = (
    ("detector", DEFAULT_DETECTOR),
    ("tracker", DEFAULT_TRACKER),
    ("tracker", EDGETAM_TRACKER),
)
_TRACKER_TYPES = ("sam2_video", "edgetam_video")
_DETECTOR_TYPES = ("grounding-dino", "mm-grounding-dino")


def fetch_command(source: str) -> str:
    """The shell command that puts `source` (a repo id) into the Hugging Face cache."""
    return f"hf download {source}"


WHERE = "--detector/--tracker (deploy track, models check) or [perception] detector/tracker (a --config file)"
"""Where a user names the models."""


def _fix(source: str) -> str:
    path = Path(source).expanduser()
    if path.is_absolute() or source.startswith(".") or path.is_dir():  # a local directory, not a repo id
        return f"point {WHERE} at a directory written by save_pretrained, or a cached repo id"
    return f"fetch it with `{fetch_command(source)}` (or point {WHERE} at a local directory)"


def resolve_checkpoint(source: str) -> Path:
    """The local directory holding `source`: the directory itself, or the cached snapshot of a repo id."""
    path = Path(source).expanduser()
    if path.is_dir():
        return path
    if path.is_file():
        raise ModelError(f"model {source} is a file, not a model directory; point {WHERE} at the "
                         "directory that holds it (config.json and the weights, as save_pretrained writes them)")
    if path.is_absolute() or source.startswith(".") or source.count("/") != 1:
        raise ModelError(f"model {source}: no such directory; {_fix(source)}")
    from huggingface_hub import snapshot_download
    from huggingface_hub.errors import LocalEntryNotFoundError

    try:
        return Path(snapshot_download(source, local_files_only=True))
    except (LocalEntryNotFoundError, FileNotFoundError, OSError, ValueError):
        raise ModelError(f"model {source} is not in the Hugging Face cache; {_fix(source)}") from None


def _model_type(directory: Path, source: str) -> str:
    import json

    try:
        config = json.loads((directory / "config.json").read_text())
    except (OSError, ValueError) as e:
        raise ModelError(f"model {source}: {directory}/config.json is missing or unreadable ({e}); "
                         f"the checkpoint is incomplete: {_fix(source)}") from None
    if not isinstance(config, dict) or not isinstance(config.get("model_type"), str):
        raise ModelError(f"model {source}: {directory}/config.json names no model_type; the checkpoint is "
                         f"incomplete: {_fix(source)}")
    return config["model_type"]


def _load(source: str, role: Role, device: str, dtype: Any) -> tuple[Any, Any]:
    """(model, processor) for `source`, on `device`, in eval mode."""
    from transformers import AutoModel, AutoModelForZeroShotObjectDetection, AutoProcessor

    directory = resolve_checkpoint(source)
    model_type = _model_type(directory, source)
    wanted = _DETECTOR_TYPES if role == "detector" else _TRACKER_TYPES
    if model_type not in wanted:
        raise ModelError(f"model {source} is a {model_type!r} model, not a {role} ({' or '.join(wanted)}); "
                         f"pass a matching checkpoint as --{role}")
    auto = AutoModelForZeroShotObjectDetection if role == "detector" else AutoModel
    try:
        model = auto.from_pretrained(directory, dtype=dtype).to(device).eval()
        processor = AutoProcessor.from_pretrained(directory)
    except ImportError as e:
        raise ModelError(f"model {source} needs a package that is not installed ({e}); install it") from None
    except Exception as e:  # transformers raises OSError, ValueError, RuntimeError, safetensors errors...
        raise ModelError(f"model {source} at {directory} does not load ({type(e).__name__}: {e}); the checkpoint "
                         f"is missing files or corrupt: delete it and {_fix(source)}") from None
    return model, processor


def load_detector(source: str, device: str = "cpu", dtype: Any = None) -> tuple[Any, Any]:
    """Grounding DINO (model, processor) from a local directory or the cache."""
    return _load(source, "detector", device, dtype)


def load_tracker(source: str, device: str = "cpu", dtype: Any = None) -> tuple[Any, Any]:
    """SAM2-video or EdgeTAM-video (model, processor) from a local directory or the cache."""
    return _load(source, "tracker", device, dtype)


@dataclass(frozen=True)
class ModelStatus:
    """One model of `deploy models check`: where it was looked for and whether it loads."""

    role: Role
    source: str
    location: str
    loads: bool
    message: str
    load_s: float | None = None
    fetch: str | None = None

    def to_dict(self) -> dict:
        return {"role": self.role, "source": self.source, "location": self.location, "loads": self.loads,
                "message": self.message, "load_s": self.load_s, "fetch": self.fetch}


def check_model(role: Role, source: str, device: str = "cpu") -> ModelStatus:
    """Look `source` up and load it on `device`; never raises for a missing or broken model."""
    from huggingface_hub.constants import HF_HUB_CACHE

    path = Path(source).expanduser()
    location = str(path) if path.is_dir() or path.is_absolute() else f"{HF_HUB_CACHE} (repo {source})"
    clock = time.perf_counter()
    try:
        directory = resolve_checkpoint(source)
        location = str(directory)
        _load(source, role, device, None)
    except ModelError as e:
        fetch = None if path.is_dir() or path.is_absolute() else fetch_command(source)
        return ModelStatus(role, source, location, False, str(e), fetch=fetch)
    return ModelStatus(role, source, location, True, "ok", round(time.perf_counter() - clock, 2))


def check_models(models: list[tuple[Role, str]] | None = None, device: str = "cpu") -> list[ModelStatus]:
    """`check_model` for each (role, source), by default the known detector and trackers."""
    return [check_model(role, source, device) for role, source in (models or list(KNOWN_MODELS))]
