"""Cameras: one protocol (`drivers.camera.base.Camera`), kinds chosen by a string (`drivers.camera.registry`)."""
