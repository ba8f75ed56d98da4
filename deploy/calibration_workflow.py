"""The calibration workflow behind `deploy calibrate intrinsics|hand-eye|check`: open the devices, offer an existing
file for reuse, plan the stations (a dry run stops there), ask before a real arm moves, run the routine
(calibration/routine.py), keep the result (calibration/store.py) and, in simulation, score it against the scene's
truth (deploy/evaluation.py). The command line only parses the options, answers the questions and prints the
`Outcome`; everything here runs the same from Python.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from calibration.board import BoardConfig
from calibration.poses import PoseConfig, intrinsics_stations
from calibration.routine import (
    RoutineConfig,
    check_pointing,
    check_poses,
    point_at_board,
    run_check,
    run_hand_eye,
    run_intrinsics,
)
from calibration.store import HandEyeRecord, intrinsics_path, load_for, load_intrinsics_for
from deploy.calibration_devices import DeviceChoice, Devices, StationPlan, open_devices
from deploy.errors import CalibrationError
from deploy.rig import SIM_SERIAL

Existing = Literal["ask", "reuse", "redo"]
Progress = Callable[[str], AbstractContextManager[Callable[[int, int], None]]]
POINT_NOTE = " Then the tool tip goes to 2 cm in front of the board's centre corner."


@dataclass(frozen=True)
class Ask:
    """How the workflow talks to the user: `reuse(path, about)` whether to reuse an existing file (`about` says
    what it holds; asked only for --existing ask); `confirm(question)` before a real arm moves (it aborts by
    raising; None: never ask, --yes); `progress(label)` a context giving a (done, total) callback."""

    reuse: Callable[[Path, str], bool]
    confirm: Callable[[str], None] | None
    progress: Progress


@dataclass(frozen=True)
class Request:
    """One calibration: the devices, the board, how many stations (their generator's seed), the setup (None for
    hand-eye and check: the stored calibration's, else eye-to-hand), what to do with an existing file, the
    calibration folder, a dry run, and the --sim-fault injections of a simulated CAN arm."""

    choice: DeviceChoice
    board: BoardConfig
    poses: int
    seed: int = 0
    setup: str | None = None
    existing: Existing = "ask"
    directory: Path | None = None
    dry_run: bool = False
    faults: list[Any] = field(default_factory=list)


@dataclass(frozen=True)
class Outcome:
    """What a calibration command did: "reused" an existing file, planned a "dry run" (`plan`), or is "done";
    `data` is its JSON, `title` names it, `warnings` are to show, `path` the file it concerns."""

    status: Literal["reused", "dry run", "done"]
    data: dict
    title: str = ""
    plan: StationPlan | None = None
    warnings: list[str] = field(default_factory=list)
    path: Path | None = None


def intrinsics(request: Request, ask: Ask) -> Outcome:
    """Fit the camera's own intrinsics from board views at `request.poses` stations and keep a fit that differs
    from the factory values (a fit that confirms them removes this camera's old file)."""
    from calibration.intrinsics import compare_with_factory

    check_poses("intrinsics", request.poses)
    setup = request.setup or "eye-to-hand"
    with _devices(request, setup) as dev:
        factory, serial, path = dev.camera.intrinsics, dev.serial, intrinsics_path(dev.serial, request.directory)
        old = load_intrinsics_for(serial, request.directory, factory) if _may_reuse(request) else None
        if old is not None and _reuse(request, ask, path, f"fx {old.intrinsics.fx:.1f}, {old.views} views, "
                                                         f"{old.created:%Y-%m-%d}"):
            return Outcome("reused", {"file": str(path), "reused": True})
        cfg = RoutineConfig(setup, request.poses, request.board, intrinsics_stations(dev.pivot(), request.seed))
        if (planned := _prepare(dev, cfg, request, ask)) is not None:
            return planned
        with ask.progress("intrinsics") as counts:
            result = run_intrinsics(dev.camera, dev.arm, dev.kin, cfg, dev.limits, counts)
    return _keep_intrinsics(result, factory, serial, path, compare_with_factory(result, factory))


def _keep_intrinsics(result, factory, serial: str, path: Path, differs: bool) -> Outcome:
    """Save a fit that differs from the factory values; for one that confirms them remove this camera's old file
    (the user chose to redo it) so that hand-eye uses the factory values."""
    from calibration.store import IntrinsicsRecord, save_intrinsics

    removed = not differs and path.is_file()
    if differs:
        save_intrinsics(IntrinsicsRecord(serial, result.intrinsics, result.distortion, result.rms_px, result.views),
                        path.parent)
    elif removed:
        path.unlink()
    data = {"file": str(path) if differs else None, "saved": differs, "removed_old_file": removed,
            "views": result.views, "rms_px": result.rms_px, "coverage": result.coverage, **result.intrinsics.to_dict(),
            "std": dict(zip(("fx", "fy", "cx", "cy"), result.std[:4].tolist(), strict=True)),
            "distortion": result.distortion.tolist(), "factory": factory.to_dict()}
    return Outcome("done", data, f"intrinsics of {serial}", path=path)


def hand_eye(request: Request, ask: Ask) -> Outcome:
    """Move through `request.poses` diverse stations, detect the board, solve, refine and save the hand-eye
    calibration of this camera and robot; in simulation, its error against the truth."""
    check_poses("hand-eye", request.poses)
    choice = request.choice
    old = load_for(SIM_SERIAL, choice.robot.name, request.directory) \
        if choice.simulated and _may_reuse(request) else None
    with _devices(request, _setup(request, old)) as dev:  # the simulated scene needs the setup
        serial, robot_id = dev.serial, dev.robot_id
        old = load_for(serial, robot_id, request.directory) if _may_reuse(request) else None
        setup = _setup(request, old)
        if old is not None and _reuse_hand_eye(request, ask, old, setup):
            return Outcome("reused", {"file": str(_hand_eye_path(old, request)), "reused": True})
        own = load_intrinsics_for(serial, request.directory, dev.camera.intrinsics)  # else the factory values
        cfg = RoutineConfig(setup, request.poses, request.board, PoseConfig(pivot_tool_m=dev.pivot(),  # type: ignore
                                                                            seed=request.seed))
        if (planned := _prepare(dev, cfg, request, ask)) is not None:
            return planned
        with ask.progress(f"hand-eye {setup}") as counts:
            run = run_hand_eye(dev.camera, dev.arm, dev.kin, cfg, dev.limits, own and own.intrinsics,
                               own and own.distortion, counts)
        path = _save(run, dev, request.board, request.directory)
        data = _hand_eye_summary(run, path) | {"camera_serial": serial, "robot_id": robot_id, "intrinsics_from":
                                               str(intrinsics_path(serial, request.directory)) if own else "factory"}
        if dev.rig is not None:  # simulation: scored against the scene's truth
            from deploy.evaluation import calibration_error

            err_mm, err_deg = calibration_error(dev.rig, run.best.T_camera)
            data |= {"true_error_mm": err_mm, "true_error_deg": err_deg}
    return Outcome("done", data, f"hand-eye {setup} ({serial} on {robot_id})")


def check(request: Request, ask: Ask, max_age_days: float = 30.0, point: bool = False) -> Outcome:
    """Check the stored calibration on fresh stations (the spread of the fixed frame, warnings); with `point`
    (eye-in-hand) move the tool tip in front of the board's centre corner."""
    check_poses("check", request.poses)
    choice = request.choice
    record = _stored(SIM_SERIAL, choice.robot.name, request.directory) if choice.simulated else None
    with _devices(request, record.setup if record else "eye-to-hand", record and record.board) as dev:
        record = record or _stored(dev.serial, dev.robot_id, request.directory)
        if point:
            check_pointing(record)
        cfg = RoutineConfig(record.setup, request.poses, record.board,  # type: ignore[arg-type]
                            PoseConfig(pivot_tool_m=dev.pivot(record), seed=request.seed))
        if (planned := _prepare(dev, cfg, request, ask, record, POINT_NOTE if point else "")) is not None:
            return planned
        with ask.progress("check") as counts:
            report = run_check(dev.camera, dev.arm, dev.kin, record, cfg, dev.limits, dev.serial, max_age_days,
                               counts)
        data = report.to_dict()
        if point:
            data |= _pointed(dev, record)
    return Outcome("done", data, f"check of {record.setup} calibration ({record.created:%Y-%m-%d})",
                   warnings=list(report.warnings))


def _pointed(dev: Devices, record: HandEyeRecord) -> dict:
    """The pointing test's figures (and in simulation its error against the true corner)."""
    pointed = point_at_board(dev.camera, dev.arm, dev.kin, record, dev.limits)
    data = {"point_corner_m": pointed.corner.tolist(), "point_reached_m": pointed.reached.tolist(),
            "point_tracking_mm": float(np.linalg.norm(pointed.reached - pointed.target) * 1e3)}
    if dev.rig is not None:
        from deploy.evaluation import true_board_corner

        data["point_true_error_mm"] = float(np.linalg.norm(pointed.corner - true_board_corner(dev.rig, record.board))
                                            * 1e3)
    return data


@contextmanager
def _devices(request: Request, setup: str, board: BoardConfig | None = None) -> Iterator[Devices]:
    """The request's devices (the board of the simulated scene: `board`, else the request's), --sim-fault
    injected."""
    with open_devices(request.choice, setup, board or request.board, request.seed) as dev:
        for fault in request.faults:
            fault.schedule(dev.motors)
        yield dev


def _prepare(dev: Devices, cfg: RoutineConfig, request: Request, ask: Ask, record: HandEyeRecord | None = None,
             note: str = "") -> Outcome | None:
    """Plan the stations; a dry run's Outcome (the plan, whether the board is visible). Otherwise ask (real arm,
    unless --yes), enable the arm and return None: go on."""
    plan = dev.plan(cfg)
    if request.dry_run:
        data = {"dry_run": True, "camera": dev.choice.camera, "serial": dev.serial, "arm": dev.choice.arm,
                "robot": dev.robot_id, "setup": cfg.setup, "pivot_tool_m": list(cfg.stations.pivot_tool_m),
                "board_visible": dev.board_visible(cfg.board, record), **plan.to_dict()}
        return Outcome("dry run", data, f"{len(plan.stations)} stations for {dev.robot_id} ({dev.choice.arm}), "
                                        f"camera {dev.serial}: dry run, nothing moved", plan)
    confirm = ask.confirm
    dev.start(plan, None if confirm is None else lambda message: confirm(message + note))
    return None


def _may_reuse(request: Request) -> bool:
    """Whether an existing file is offered for reuse: not on a dry run, not when the request redoes it."""
    return not request.dry_run and request.existing != "redo"


def _reuse(request: Request, ask: Ask, path: Path, about: str) -> bool:
    """Whether to reuse the existing file at `path`: --existing, else the user's answer."""
    return request.existing == "reuse" or (request.existing == "ask" and ask.reuse(path, about))


def _setup(request: Request, old: HandEyeRecord | None) -> str:
    """--setup, else the stored calibration's, else eye-to-hand."""
    return request.setup or (old.setup if old is not None else "eye-to-hand")


def _hand_eye_path(old: HandEyeRecord, request: Request) -> Path:
    from calibration.store import hand_eye_path

    return hand_eye_path(old.camera_serial, old.robot_id, request.directory)


def _reuse_hand_eye(request: Request, ask: Ask, old: HandEyeRecord, setup: str) -> bool:
    """Whether to reuse the stored calibration `old`; CalibrationError when it is of another setup."""
    path = _hand_eye_path(old, request)
    if old.setup != setup:
        raise CalibrationError(f"{path} holds an {old.setup} calibration, not {setup}: pass --existing redo to "
                               f"replace it, or --setup {old.setup} to reuse it")
    return _reuse(request, ask, path, f"{old.setup}, {old.method}, {old.created:%Y-%m-%d}, spread "
                                      f"{old.spread_mm:.1f} mm")


def _stored(serial: str, robot_id: str, directory: Path | None) -> HandEyeRecord:
    record = load_for(serial, robot_id, directory)
    if record is None:
        raise CalibrationError(f"no hand-eye calibration for camera {serial} on robot {robot_id}: run "
                               "`deploy calibrate hand-eye` first")
    return record


def _save(run, dev: Devices, board: BoardConfig, directory: Path | None) -> Path:
    """The run's best solution as the calibration file of this camera and robot."""
    from calibration.store import HandEyeRecord, save_hand_eye

    best = run.best
    record = HandEyeRecord(
        camera_serial=dev.serial, robot_id=dev.robot_id, setup=best.setup,
        method=best.method + ("+refined" if best.refined else ""), T_camera=best.T_camera, T_board=best.T_board,
        tool_frame=dev.kin.tool_frame, intrinsics=run.intrinsics, distortion=run.distortion,
        reprojection_px=best.reprojection_px, spread_mm=best.spread_mm, spread_deg=best.spread_deg,
        samples=best.samples, board=board,
    )
    return save_hand_eye(record, directory)


def _hand_eye_summary(run, path: Path) -> dict:
    best = run.best
    return {
        "file": str(path), "setup": best.setup, "method": best.method, "refined": best.refined,
        "intrinsics": run.intrinsics.to_dict(),
        "samples": best.samples, "missed_poses": len(run.collection.missed), "reprojection_px": best.reprojection_px,
        "spread_mm": best.spread_mm, "spread_deg": best.spread_deg, "T_camera": best.T_camera.tolist(),
        "methods": [{"method": s.method, "spread_mm": s.spread_mm, "spread_deg": s.spread_deg,
                     "reprojection_px": s.reprojection_px} for s in run.solutions],
    }
