"""Axis estimators, chosen by name (`--estimator`)."""

from __future__ import annotations

from deploy.geometry.estimators.base import AxisEstimator, Observation

ESTIMATOR_NAMES = ("paper-obb", "screw", "screw-grip", "trajectory")


def make_estimator(name: str) -> AxisEstimator:
    """A fresh estimator by name: "paper-obb" (the paper's rules), "screw" (registration of the moving part
    across the window), "screw-grip" (the same, with the gripper's path), "trajectory" (fit to the
    gripper's own path)."""
    if name == "paper-obb":
        from deploy.geometry.estimators.paper_obb import PaperOBBEstimator

        return PaperOBBEstimator()
    if name == "screw":
        from deploy.geometry.estimators.screw import ScrewEstimator

        return ScrewEstimator()
    if name == "screw-grip":
        from deploy.geometry.estimators.screw import ScrewGripEstimator

        return ScrewGripEstimator()
    if name == "trajectory":
        from deploy.geometry.estimators.trajectory import TrajectoryEstimator

        return TrajectoryEstimator()
    raise ValueError(f"unknown estimator {name!r}: choose one of {', '.join(ESTIMATOR_NAMES)}")


__all__ = ["AxisEstimator", "Observation", "ESTIMATOR_NAMES", "make_estimator"]
