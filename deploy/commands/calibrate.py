"""`deploy calibrate board|intrinsics|hand-eye|check`: ChArUco board, intrinsics, hand-eye and its check."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

from deploy.commands.options import (
    JsonOpt,
    SimFaultOpt,
    StationSeedOpt,
    above,
    dry_run_option,
    kind_option,
    robot_option,
    yes_option,
)
from deploy.commands.output import console, err_console, print_json, print_rows, print_table, progress_bar
from drivers.arm.registry import ARMS
from drivers.camera.registry import CAMERAS

app = typer.Typer(help="Field calibration: ChArUco board, intrinsics, hand-eye, checks.", no_args_is_help=True)


class SetupChoice(str, Enum):
    eye_to_hand = "eye-to-hand"
    eye_in_hand = "eye-in-hand"


class ExistingChoice(str, Enum):
    ask = "ask"
    reuse = "reuse"
    redo = "redo"


CameraOpt = kind_option(CAMERAS, "--camera", " A D415's serial names the calibration file; a recording cannot "
                        "calibrate.")
ArmOpt = kind_option(ARMS, "--arm", " \\[default: sim with the sim camera, can with a D415].", optional=True)
RobotOpt = robot_option("Robot config (a shipped one's name or a TOML file); its name names the calibration file "
                        "(required for --arm can; default for sim arms: panda_sim).")
PivotOpt = Annotated[tuple[float, float, float] | None, typer.Option(
    "--pivot-mm", help="Point (mm, tool frame) the stations turn about: eye-to-hand the board centre, eye-in-hand the "
    "point the wrist camera looks at (required on a real arm, except for check: from the stored calibration; "
    "sim: the rig's).")]
YesOpt = yes_option("Do not ask before a real arm moves.")
DryRunOpt = dry_run_option("Open the camera, read the arm's joints, plan and print the stations; enable and move "
                           "nothing.")
SetupOpt = Annotated[SetupChoice, typer.Option("--setup", help="eye-to-hand (fixed camera, board on the tool) or "
                                               "eye-in-hand (wrist camera, board fixed).")]
HandEyeSetupOpt = Annotated[SetupChoice | None, typer.Option(
    "--setup", help="eye-to-hand (fixed camera, board on the tool) or eye-in-hand (wrist camera, board fixed) "
    "\\[default: the stored calibration's, else eye-to-hand].", show_default=False)]
ExistingOpt = Annotated[ExistingChoice, typer.Option("--existing", help="When the calibration file exists: ask, "
                                                  "reuse it, or redo it.")]
PosesOpt = Annotated[int, typer.Option("--poses", min=1, help="Stations the arm visits.")]
DirOpt = Annotated[Path | None, typer.Option("--dir", help="Calibration folder (default: $AXISLOOP_CALIBRATION_DIR "
                                             "or ~/.config/axisloop/calibration).")]
SquaresOpt = Annotated[str, typer.Option("--squares", help="Board squares, COLSxROWS.")]
SquareMmOpt = Annotated[float, typer.Option("--square-mm", min=1.0, help="Square side as printed (mm).")]
MarkerMmOpt = Annotated[float, typer.Option("--marker-mm", min=1.0, help="Marker side as printed (mm).")]
DictOpt = Annotated[str, typer.Option("--dictionary", help="OpenCV ArUco dictionary.")]
LegacyOpt = Annotated[bool, typer.Option("--legacy", help="Board printed by OpenCV < 4.6 (legacy ChArUco pattern).")]


def _board(squares: str, square_mm: float, marker_mm: float, dictionary: str, legacy: bool):
    from calibration.board import BoardConfig
    from deploy.errors import ConfigError

    try:
        cols, rows = (int(v) for v in squares.lower().split("x"))
    except ValueError as exc:
        raise ConfigError(f"--squares {squares!r} is not COLSxROWS: write e.g. 5x7") from exc
    return BoardConfig((cols, rows), square_mm / 1000, marker_mm / 1000, dictionary, legacy)


@app.command("board")
def board_cmd(
    out: Annotated[Path, typer.Option("--out", help="PNG or PDF to write (true scale).")] = Path("board.pdf"),
    squares: SquaresOpt = "5x7", square_mm: SquareMmOpt = 38.0, marker_mm: MarkerMmOpt = 28.0,
    dictionary: DictOpt = "DICT_4X4_50", legacy: LegacyOpt = False,
    dpi: Annotated[float, typer.Option("--dpi", min=72.0, help="Print resolution.")] = 300.0,
    json_out: JsonOpt = False,
) -> None:
    """Render a printable ChArUco board at true scale: print at 100 %, then measure one square.

    Example: deploy calibrate board --out board.pdf --squares 5x7 --square-mm 38 --marker-mm 28
    """
    from calibration.board import write_board

    cfg = _board(squares, square_mm, marker_mm, dictionary, legacy)
    write_board(cfg, out, dpi)
    w, h = cfg.size_m
    if json_out:
        print_json({"out": str(out), "squares": squares, "square_mm": square_mm, "marker_mm": marker_mm,
                    "dictionary": dictionary, "width_mm": w * 1e3, "height_mm": h * 1e3, "dpi": dpi})
    else:
        console.print(f"wrote {out}: {squares} squares of {square_mm:g} mm ({w * 1e3:.0f} x {h * 1e3:.0f} mm)")


def _prepare(dev, cfg, board, dry_run: bool, yes: bool, json_out: bool, record=None, note: str = "") -> bool:
    """Plan the stations; dry run: print them and return False. Otherwise ask (real arm, unless --yes),
    enable the arm and return True."""
    plan = dev.plan(cfg)
    if dry_run:
        data = {"dry_run": True, "camera": dev.choice.camera, "serial": dev.serial, "arm": dev.choice.arm,
                "robot": dev.robot_id, "setup": cfg.setup, "pivot_tool_m": list(cfg.stations.pivot_tool_m),
                "board_visible": dev.board_visible(board, record), **plan.to_dict()}
        if json_out:
            print_json(data)
            return False
        print_table(f"{len(plan.stations)} stations for {dev.robot_id} ({dev.choice.arm}), camera {dev.serial}: "
                    "dry run, nothing moved", ("#", "joints (rad)", "tool position (m)", "turn (deg)"),
                    [(str(i + 1), " ".join(f"{v:+.3f}" for v in s["q"]),
                      " ".join(f"{v:.3f}" for v in s["tool_position_m"]), f"{s['turn_deg']:.1f}")
                     for i, s in enumerate(data["stations"])])
        console.print(f"board visible at the start pose: {data['board_visible']}; about {plan.duration_s:.0f} s; "
                      f"tool within {plan.max_shift_m * 100:.1f} cm and {plan.max_turn_deg:.1f} deg of its start")
        return False
    dev.start(plan, None if yes else lambda message: typer.confirm(message + note, abort=True, err=True))
    return True


@app.command("intrinsics")
def intrinsics_cmd(
    camera: CameraOpt = "sim", arm: ArmOpt = None, robot: RobotOpt = None, pivot_mm: PivotOpt = None,
    poses: PosesOpt = 12, setup: SetupOpt = SetupChoice.eye_to_hand,
    squares: SquaresOpt = "5x7", square_mm: SquareMmOpt = 38.0, marker_mm: MarkerMmOpt = 28.0,
    dictionary: DictOpt = "DICT_4X4_50", legacy: LegacyOpt = False, existing: ExistingOpt = ExistingChoice.ask,
    directory: DirOpt = None, yes: YesOpt = False, dry_run: DryRunOpt = False, seed: StationSeedOpt = 0,
    sim_fault: SimFaultOpt = None, json_out: JsonOpt = False,
) -> None:
    """Fit the camera's own intrinsics from board views at N stations (default: RealSense factory values).

    The fit is saved (and hand-eye uses it) only when it is precise and differs significantly from the factory
    values; one that confirms them saves nothing; an unreliable or implausible one is refused.

    Example: deploy calibrate intrinsics --camera d415 --arm can --robot my_arm.toml --pivot-mm 0 0 30 --poses 12
    """
    from calibration.intrinsics import compare_with_factory
    from calibration.poses import intrinsics_stations
    from calibration.routine import RoutineConfig, check_poses, run_intrinsics
    from calibration.store import intrinsics_path, load_intrinsics_for
    from deploy.arm_bringup import parse_sim_faults
    from deploy.calibration_devices import choose, open_devices

    check_poses("intrinsics", poses)
    choice = choose(camera, arm, robot, pivot_mm)
    faults = parse_sim_faults(choice.arm, sim_fault)
    board = _board(squares, square_mm, marker_mm, dictionary, legacy)
    with open_devices(choice, setup.value, board, seed) as dev:
        _inject(dev, faults)
        factory, serial, path = dev.camera.intrinsics, dev.serial, intrinsics_path(dev.serial, directory)
        old = load_intrinsics_for(serial, directory, factory) if existing != ExistingChoice.redo and not dry_run \
            else None
        if old is not None and _reuse(existing, path, f"fx {old.intrinsics.fx:.1f}, {old.views} views, "
                                                      f"{old.created:%Y-%m-%d}", json_out):
            return
        cfg = RoutineConfig(setup.value, poses, board, intrinsics_stations(dev.pivot(), seed))
        if not _prepare(dev, cfg, board, dry_run, yes, json_out):
            return
        with progress_bar("intrinsics") as bar:
            result = run_intrinsics(dev.camera, dev.arm, dev.kin, cfg, dev.limits, bar.counts)
    _keep_intrinsics(result, factory, serial, path, compare_with_factory(result, factory), json_out)


def _keep_intrinsics(result, factory, serial: str, path: Path, differs: bool, json_out: bool) -> None:
    """Save a fit that differs from the factory values; for one that confirms them remove this camera's old file
    (the user chose to redo it) so that hand-eye uses the factory values. Print the outcome."""
    from calibration.intrinsics import SIGNIFICANT_SIGMAS
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
    if json_out:
        print_json(data)
        return
    print_rows(f"intrinsics of {serial}", {k: v for k, v in data.items() if k not in ("factory", "std")}, digits=4)
    if differs:
        console.print(f"saved {path}: they differ from the factory values by more than {SIGNIFICANT_SIGMAS:g} sigma; "
                      "hand-eye uses them from now on")
    else:
        console.print(f"the fit agrees with the factory values within {SIGNIFICANT_SIGMAS:g} sigma: nothing saved, "
                      "hand-eye uses the factory values" + (f" (removed the old {path})" if removed else ""))


def _reuse(existing: ExistingChoice, path: Path, about: str, json_out: bool) -> bool:
    """Whether to reuse the existing file at `path` (--existing, else the user's answer, default yes); print it
    when reused. ConfigError naming --existing when nobody can answer."""
    from deploy.errors import ConfigError

    if existing == ExistingChoice.ask:
        try:
            reuse = typer.confirm(f"{path} exists ({about}): reuse it?", default=True, err=True)
        except typer.Abort as exc:
            if not isinstance(exc.__context__, EOFError):
                raise
            typer.echo(err=True)  # end the question's line
            raise ConfigError(f"{path} exists and standard input is closed, so whether to reuse it cannot be asked: "
                              "pass --existing reuse or --existing redo") from exc
    else:
        reuse = existing == ExistingChoice.reuse
    if reuse:
        if json_out:
            print_json({"file": str(path), "reused": True})
        else:
            console.print(f"reusing {path}")
    return reuse


@app.command("hand-eye")
def hand_eye_cmd(
    setup: HandEyeSetupOpt = None, poses: PosesOpt = 15, camera: CameraOpt = "sim", arm: ArmOpt = None,
    robot: RobotOpt = None, pivot_mm: PivotOpt = None, squares: SquaresOpt = "5x7", square_mm: SquareMmOpt = 38.0,
    marker_mm: MarkerMmOpt = 28.0, dictionary: DictOpt = "DICT_4X4_50", legacy: LegacyOpt = False,
    existing: ExistingOpt = ExistingChoice.ask,
    directory: DirOpt = None, yes: YesOpt = False, dry_run: DryRunOpt = False, seed: StationSeedOpt = 0,
    sim_fault: SimFaultOpt = None, json_out: JsonOpt = False,
) -> None:
    """Hand-eye: move through N diverse poses, detect the board, solve, refine and save the calibration.

    Several solvers run; the most consistent one is refined on the corners' reprojection error. The file is
    one per camera serial and robot config name; an existing one is offered for reuse first (--existing reuse|redo
    answers in advance; a file of another --setup is never reused). A real arm asks before it moves (--yes
    skips); --dry-run prints the stations and moves nothing.

    Example: deploy calibrate hand-eye --camera d415 --arm can --robot my_arm.toml --pivot-mm 0 0 30 --poses 15
    """
    from calibration.poses import PoseConfig
    from calibration.routine import RoutineConfig, check_poses, run_hand_eye
    from calibration.store import intrinsics_path, load_for, load_intrinsics_for
    from deploy.arm_bringup import parse_sim_faults
    from deploy.calibration_devices import choose, open_devices
    from deploy.rig import SIM_SERIAL

    check_poses("hand-eye", poses)
    choice = choose(camera, arm, robot, pivot_mm)
    faults = parse_sim_faults(choice.arm, sim_fault)
    board = _board(squares, square_mm, marker_mm, dictionary, legacy)
    reusable = not dry_run and existing != ExistingChoice.redo
    old = load_for(SIM_SERIAL, choice.robot.name, directory) if reusable and choice.simulated else None
    with open_devices(choice, _setup_name(setup, old), board, seed) as dev:  # the sim scene needs the setup
        _inject(dev, faults)
        serial, robot_id = dev.serial, dev.robot_id
        old = load_for(serial, robot_id, directory) if reusable else None
        setup_name = _setup_name(setup, old)
        if old is not None and _reuse_hand_eye(old, setup_name, existing, directory, json_out):
            return
        own = load_intrinsics_for(serial, directory, dev.camera.intrinsics)  # else the camera's factory values
        cfg = RoutineConfig(setup_name, poses, board, PoseConfig(pivot_tool_m=dev.pivot(), seed=seed))
        if not _prepare(dev, cfg, board, dry_run, yes, json_out):
            return
        with progress_bar(f"hand-eye {setup_name}") as bar:
            run = run_hand_eye(dev.camera, dev.arm, dev.kin, cfg, dev.limits, own and own.intrinsics,
                               own and own.distortion, bar.counts)
        path = _save(run, dev, board, directory)
        data = _hand_eye_summary(run, path) | {"camera_serial": serial, "robot_id": robot_id,
                                               "intrinsics_from": str(intrinsics_path(serial, directory)) if own
                                               else "factory"}
        if dev.rig is not None:  # simulation: scored against the scene's truth
            from deploy.evaluation import calibration_error

            err_mm, err_deg = calibration_error(dev.rig, run.best.T_camera)
            data |= {"true_error_mm": err_mm, "true_error_deg": err_deg}
    if json_out:
        print_json(data)
    else:
        rows = {k: v for k, v in data.items() if k != "methods"}
        print_rows(f"hand-eye {setup_name} ({serial} on {robot_id})", rows, digits=4)


def _setup_name(setup: SetupChoice | None, old) -> str:
    """--setup, else the stored calibration's, else eye-to-hand."""
    return setup.value if setup is not None else old.setup if old is not None else SetupChoice.eye_to_hand.value


def _reuse_hand_eye(old, setup: str, existing: ExistingChoice, directory: Path | None, json_out: bool) -> bool:
    """Whether to reuse the stored calibration `old` (see `_reuse`); CalibrationError when it is of another setup."""
    from calibration.store import hand_eye_path
    from deploy.errors import CalibrationError

    path = hand_eye_path(old.camera_serial, old.robot_id, directory)
    if old.setup != setup:
        raise CalibrationError(f"{path} holds an {old.setup} calibration, not {setup}: pass --existing redo to "
                               f"replace it, or --setup {old.setup} to reuse it")
    return _reuse(existing, path, f"{old.setup}, {old.method}, {old.created:%Y-%m-%d}, spread {old.spread_mm:.1f} mm",
                  json_out)


@app.command("check")
def check_cmd(
    camera: CameraOpt = "sim", arm: ArmOpt = None, robot: RobotOpt = None, pivot_mm: PivotOpt = None,
    poses: PosesOpt = 6,
    max_age_days: Annotated[float, typer.Option("--max-age-days", callback=above(0.0), help="Warn when older.")
                            ] = 30.0,
    point: Annotated[bool, typer.Option("--point", help="Eye-in-hand: move the tool tip to 2 cm in front of "
                                        "the board's centre corner.")] = False,
    directory: DirOpt = None, yes: YesOpt = False, dry_run: DryRunOpt = False, seed: StationSeedOpt = 1,
    sim_fault: SimFaultOpt = None, json_out: JsonOpt = False,
) -> None:
    """Check the stored calibration: spread of the fixed frame over fresh poses, a one-shot test, warnings.

    Example: deploy calibrate check --camera d415 --arm can --robot my_arm.toml --poses 6 --json
    """
    import numpy as np

    from calibration.poses import PoseConfig
    from calibration.routine import RoutineConfig, check_pointing, check_poses, point_at_board, run_check
    from calibration.store import load_for
    from deploy.arm_bringup import parse_sim_faults
    from deploy.calibration_devices import choose, open_devices
    from deploy.errors import CalibrationError
    from deploy.rig import SIM_SERIAL

    def stored(serial: str, robot_id: str):
        record = load_for(serial, robot_id, directory)
        if record is None:
            raise CalibrationError(f"no hand-eye calibration for camera {serial} on robot {robot_id}: run "
                                   "`deploy calibrate hand-eye` first")
        return record

    check_poses("check", poses)
    choice = choose(camera, arm, robot, pivot_mm, pivot_from_record=True)
    faults = parse_sim_faults(choice.arm, sim_fault)
    record = stored(SIM_SERIAL, choice.robot.name) if choice.simulated else None  # the rig needs its setup
    with open_devices(choice, record.setup if record else "eye-to-hand", record and record.board, seed) as dev:
        _inject(dev, faults)
        record = record or stored(dev.serial, dev.robot_id)
        if point:
            check_pointing(record)
        cfg = RoutineConfig(record.setup, poses, record.board,  # type: ignore[arg-type]
                            PoseConfig(pivot_tool_m=dev.pivot(record), seed=seed))
        note = " Then the tool tip goes to 2 cm in front of the board's centre corner." if point else ""
        if not _prepare(dev, cfg, record.board, dry_run, yes, json_out, record, note):
            return
        with progress_bar("check") as bar:
            report = run_check(dev.camera, dev.arm, dev.kin, record, cfg, dev.limits, dev.serial, max_age_days,
                               bar.counts)
        data = report.to_dict()
        if point:
            pointed = point_at_board(dev.camera, dev.arm, dev.kin, record, dev.limits)
            data |= {"point_corner_m": pointed.corner.tolist(), "point_reached_m": pointed.reached.tolist(),
                     "point_tracking_mm": float(np.linalg.norm(pointed.reached - pointed.target) * 1e3)}
            if dev.rig is not None:
                data["point_true_error_mm"] = float(np.linalg.norm(pointed.corner
                                                                   - _true_corner(dev.rig, record.board)) * 1e3)
    for warning in report.warnings:
        err_console.print(f"[yellow]warning:[/] {warning}", highlight=False)
    if json_out:
        print_json(data)
    else:
        print_rows(f"check of {record.setup} calibration ({record.created:%Y-%m-%d})", data, digits=4)


def _inject(dev, faults) -> None:
    """Schedule the --sim-fault faults on the simulated motors of a sim-can calibration arm."""
    for fault in faults:
        fault.schedule(dev.motors)


def _save(run, dev, board, directory: Path | None) -> Path:
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


def _true_corner(rig, board):
    """Ground truth (sim only): the base position of the board corner nearest its centre."""
    import numpy as np

    points = np.asarray(board.board().getChessboardCorners(), float)
    p = points[np.argmin(np.linalg.norm(points - board.center_m, axis=1))]
    return rig.true_board[:3, :3] @ p + rig.true_board[:3, 3]
