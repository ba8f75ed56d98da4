"""Segmenter backends, chosen by name (`--segmenter`)."""

from __future__ import annotations

from deploy.errors import ConfigError
from deploy.perception.base import Segmenter

SEGMENTER_NAMES = ("oracle",)


def make_segmenter(name: str) -> Segmenter:
    """A fresh segmenter by name: "oracle" (simulation labels)."""
    if name == "oracle":
        from deploy.perception.oracle import OracleSegmenter

        return OracleSegmenter()
    raise ConfigError(f"unknown segmenter {name!r}: choose one of {', '.join(SEGMENTER_NAMES)}")


__all__ = ["Segmenter", "SEGMENTER_NAMES", "make_segmenter"]
