"""Shared test set-up: single-threaded BLAS (threads busy-wait on 2 cores and slow everything)."""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

from contextlib import contextmanager  # noqa: E402

import pytest  # noqa: E402

import deploy.calibration_workflow as workflow  # noqa: E402
from drivers.arm.robot_config import PANDA_SIM_CONFIG  # noqa: E402

NEAR_DOORS_M = (0.4, 0.7)  # the scenario's door distances before RGBManip's 0.5-0.85 m: scenes some tests need


@pytest.fixture
def near_doors(tmp_path):
    """A simulated Panda's robot config whose scenes place doors 0.4-0.7 m from it, where some swing into the arm's
    own column or are grasped pressed (its `reach`)."""
    path = tmp_path / "panda_near_doors.toml"
    near = f"[reach]\ndoor_distance_m = {list(NEAR_DOORS_M)}\n"
    path.write_text(PANDA_SIM_CONFIG.read_text().replace("[reach]\n", near))
    return path


@pytest.fixture
def opened(monkeypatch):
    """The Devices each command opened (the real ones: this only keeps a reference to look at afterwards)."""
    seen = []
    real = workflow.open_devices

    @contextmanager
    def keep(*args, **kwargs):
        with real(*args, **kwargs) as dev:
            seen.append(dev)
            yield dev

    monkeypatch.setattr(workflow, "open_devices", keep)
    return seen
