"""Cameras: one protocol (`Camera`), implementations chosen by a string in `deploy`'s factory."""

from drivers.camera.base import Camera, Frame, Intrinsics, SegLabel

__all__ = ["Camera", "Frame", "Intrinsics", "SegLabel"]
