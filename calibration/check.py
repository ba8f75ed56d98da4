"""Checks of a stored hand-eye calibration: spread of the base-fixed frame over fresh samples, a one-shot
prediction test, and warnings for an old calibration or another camera."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime

import numpy as np

from calibration.hand_eye import Sample, evaluate
from calibration.intrinsics import MAX_FACTORY_OFFSET, factory_offset
from calibration.store import HandEyeRecord
from calibration.transforms import inv, mean_pose
from drivers.camera.base import Intrinsics


@dataclass(frozen=True)
class CheckReport:
    """spread_mm/deg: the base-fixed frame (eye-in-hand: board; eye-to-hand: camera) over the samples with the
    stored camera transform; reprojection_px over all samples; one_shot_mm: eye-to-hand, the board's centre
    corner seen by the camera vs where forward kinematics and the stored board mount put it (last sample);
    eye-in-hand, None here (the routine's pointing test measures it); warnings: age, serial, intrinsics."""

    spread_mm: float
    spread_deg: float
    reprojection_px: float
    one_shot_mm: float | None
    samples: int
    warnings: list[str]

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def staleness_warnings(record: HandEyeRecord, camera_serial: str, max_age_days: float,
                       now: datetime | None = None, factory: Intrinsics | None = None) -> list[str]:
    """Warnings for a calibration older than `max_age_days`, made with another camera serial, or solved with
    intrinsics far from the camera's `factory` ones (a scale error that its own reprojection cannot show)."""
    warnings = []
    offset = factory and factory_offset(record.intrinsics, factory)
    if offset:
        warnings.append(f"calibration was solved with intrinsics whose {offset} (factory) differ by more than "
                        f"{MAX_FACTORY_OFFSET:.0%}: its distances may be off by as much; delete the intrinsics file "
                        "and run `deploy calibrate hand-eye --existing redo`")
    age = record.age_days(now)
    if age > max_age_days:
        warnings.append(f"calibration is {age:.0f} days old (limit {max_age_days:g}): the camera or its mount may "
                        "have moved since; run `deploy calibrate hand-eye` again")
    if record.camera_serial != camera_serial:
        warnings.append(f"calibration was made with camera {record.camera_serial}, this is {camera_serial}: "
                        "calibrate this camera")
    return warnings


def corner_in_base(record: HandEyeRecord, sample: Sample, corner_id: int | None = None) -> np.ndarray:
    """Base-frame position (m) of a detected chessboard corner (default: the one nearest the board centre) as
    the camera sees it through the stored calibration."""
    view = sample.view
    k = int(np.argmin(np.linalg.norm(view.points - record.board.center_m, axis=1))) if corner_id is None else \
        int(np.flatnonzero(view.ids == corner_id)[0])
    p_camera = sample.T_camera_board[:3, :3] @ view.points[k] + sample.T_camera_board[:3, 3]
    T = record.T_base_camera(sample.T_base_tool)
    return T[:3, :3] @ p_camera + T[:3, 3]


def check_samples(record: HandEyeRecord, samples: Sequence[Sample], camera_serial: str, max_age_days: float = 30.0,
                  factory: Intrinsics | None = None, now: datetime | None = None) -> CheckReport:
    """Evaluate the stored camera transform on fresh samples. The board's own transform (on the tool or on the
    table) is estimated from the samples for the spread, so a board moved since calibration is no error there."""
    eye_in_hand = record.setup == "eye-in-hand"
    A = inv(record.T_camera)
    M = [inv(s.T_base_tool) if eye_in_hand else s.T_base_tool for s in samples]
    B = mean_pose([inv(m) @ record.T_camera @ s.T_camera_board for m, s in zip(M, samples, strict=True)])
    result = evaluate(samples, record.setup, record.method, A, B, record.intrinsics.K, record.distortion)
    one_shot = None
    if not eye_in_hand:
        last = samples[-1]
        seen = corner_in_base(record, last)
        view = last.view
        k = int(np.argmin(np.linalg.norm(view.points - record.board.center_m, axis=1)))
        T = last.T_base_tool @ record.T_board
        one_shot = float(np.linalg.norm(seen - (T[:3, :3] @ view.points[k] + T[:3, 3])) * 1e3)
    return CheckReport(result.spread_mm, result.spread_deg, result.reprojection_px, one_shot, len(samples),
                       staleness_warnings(record, camera_serial, max_age_days, now, factory))
