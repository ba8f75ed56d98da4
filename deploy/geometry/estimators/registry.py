"""Axis estimators, chosen by name (`--estimator`): `make_estimator(name, config)`."""

from __future__ import annotations

from typing import TYPE_CHECKING

from deploy.errors import ConfigError
from drivers.registry import Registry

if TYPE_CHECKING:
    from deploy.geometry.estimators.base import AxisEstimator

ESTIMATORS: Registry[AxisEstimator] = Registry("estimator", ConfigError)
ESTIMATORS.register("screw-grip", "deploy.geometry.estimators.screw:open_screw_grip",
                    "moving-part registration + the gripper's path")
ESTIMATORS.register("screw", "deploy.geometry.estimators.screw:open_screw",
                    "moving-part registration (vision only)")
ESTIMATORS.register("trajectory", "deploy.geometry.estimators.trajectory:open_trajectory",
                    "a line or circle fitted to the gripper's path")
ESTIMATORS.register("paper-obb", "deploy.geometry.estimators.paper_obb:open_paper_obb",
                    "the paper's box rules")


def make_estimator(name: str, config: object | None = None) -> AxisEstimator:
    """A fresh estimator of kind `name`; `config` is the run's estimator section (EstimatorConfig), if any."""
    return ESTIMATORS.open(name, config)

