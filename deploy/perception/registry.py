"""Segmenter backends, chosen by name (`--segmenter`): `make_segmenter(name, config)`."""

from __future__ import annotations

from typing import TYPE_CHECKING

from deploy.errors import ConfigError
from drivers.registry import Registry

if TYPE_CHECKING:
    from deploy.perception.base import Segmenter
    from deploy.perception.config import PerceptionConfig

SEGMENTERS: Registry[Segmenter] = Registry("segmenter", ConfigError)
SEGMENTERS.register("rgbd", "deploy.perception.rgbd:open_rgbd",
                    "no weights: furniture found in the depth image, followed in 3D (needs the camera pose)")
SEGMENTERS.register("gdino-sam2", "deploy.perception.gdino_sam2:open_gdino_sam2",
                    "Grounding DINO + SAM2 (needs model weights)", needs=("weights",))
SEGMENTERS.register("classical", "deploy.perception.classical:open_classical",
                    "no weights: a first box tracked by depth and colour", needs=("box",))
SEGMENTERS.register("oracle", "deploy.perception.oracle:open_oracle",
                    "ablation: simulator labels or stored masks", needs=("labels",))


def default_segmenter(config: PerceptionConfig | None = None) -> str:
    """`gdino-sam2` when its detector and tracker weights are on this machine, else `rgbd` (no weights)."""
    from deploy.errors import ModelError
    from deploy.perception.config import PerceptionConfig
    from deploy.perception.models import resolve_checkpoint

    config = config or PerceptionConfig()
    try:
        resolve_checkpoint(config.detector)
        resolve_checkpoint(config.tracker)
    except ModelError:
        return "rgbd"
    return "gdino-sam2"


def needs(name: str, what: str) -> bool:
    """Whether segmenter `name` needs `what` ("labels", "box", "weights": `Entry.needs`)."""
    return what in SEGMENTERS.entry(name)[0].needs


def make_segmenter(name: str, config: PerceptionConfig | None = None) -> Segmenter:
    """A fresh segmenter of kind `name` with `config` (default settings when None)."""
    from deploy.perception.config import PerceptionConfig

    return SEGMENTERS.open(name, config or PerceptionConfig())
