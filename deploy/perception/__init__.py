"""Segmenter backends, chosen by name (`--segmenter`)."""

from __future__ import annotations

from deploy.errors import ConfigError
from deploy.perception.base import Segmenter
from deploy.perception.config import PerceptionConfig

SEGMENTER_NAMES = ("oracle", "gdino-sam2", "classical")


def make_segmenter(name: str, config: PerceptionConfig | None = None) -> Segmenter:
    """A fresh segmenter by name: "oracle" (simulation labels), "gdino-sam2" (Grounding DINO + SAM2/EdgeTAM,
    loads the models named in `config`; raises ModelError if they are missing) or "classical" (no weights;
    needs `config.box`)."""
    config = config or PerceptionConfig()
    if name == "oracle":
        from deploy.perception.oracle import OracleSegmenter

        return OracleSegmenter()
    if name == "gdino-sam2":
        from deploy.perception.gdino_sam2 import GdinoSam2Segmenter

        return GdinoSam2Segmenter.from_config(config)
    if name == "classical":
        from deploy.perception.classical import ClassicalSegmenter

        return ClassicalSegmenter(config)
    raise ConfigError(f"unknown segmenter {name!r}: choose one of {', '.join(SEGMENTER_NAMES)}")


__all__ = ["Segmenter", "PerceptionConfig", "SEGMENTER_NAMES", "make_segmenter"]
