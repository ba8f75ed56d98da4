"""Synthetic articulated cabinets rendered by a pure-numpy ray caster (fast, no simulator needed)."""

from deploy.synthetic.cabinet import Kind, SyntheticCabinet
from deploy.synthetic.raycast import render, render_rgbd
from deploy.synthetic.sequence import SyntheticSequence, synthetic_sequence, write_sequence

__all__ = [
    "Kind", "SyntheticCabinet", "SyntheticSequence", "render", "render_rgbd", "synthetic_sequence",
    "write_sequence",
]
