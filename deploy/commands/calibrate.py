"""`deploy calibrate board|intrinsics|hand-eye|check` and `deploy bench calibration` (registered by deploy/cli.py)."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

SIM_SERIAL = "sim-d415"  # the simulated camera's serial, naming its calibration files


class SetupChoice(str, Enum):
    eye_to_hand = "eye-to-hand"
    eye_in_hand = "eye-in-hand"


class ExistingChoice(str, Enum):
    ask = "ask"
    reuse = "reuse"
    redo = "redo"


JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object instead of a table.")]
CameraOpt = Annotated[str, typer.Option("--camera", help="Camera: sim (PyBullet D415 rig); real cameras come with "
                                        "the camera factory.")]
ArmOpt = Annotated[str, typer.Option("--arm", help="Arm: sim (PyBullet Panda); real arms come with the arm factory.")]
SetupOpt = Annotated[SetupChoice, typer.Option("--setup", help="eye-to-hand (fixed camera, board on the tool) or "
                                               "eye-in-hand (wrist camera, board fixed).")]
PosesOpt = Annotated[int, typer.Option("--poses", min=1, help="Stations the arm visits.")]
RobotIdOpt = Annotated[str, typer.Option("--robot-id", help="Robot id naming the calibration file.")]
DirOpt = Annotated[Path | None, typer.Option("--dir", help="Calibration folder [default: $AXISLOOP_CALIBRATION_DIR "
                                             "or ~/.config/axisloop/calibration].")]
SquaresOpt = Annotated[str, typer.Option("--squares", help="Board squares, COLSxROWS.")]
SquareMmOpt = Annotated[float, typer.Option("--square-mm", min=1.0, help="Square side as printed (mm).")]
MarkerMmOpt = Annotated[float, typer.Option("--marker-mm", min=1.0, help="Marker side as printed (mm).")]
DictOpt = Annotated[str, typer.Option("--dictionary", help="OpenCV ArUco dictionary.")]
LegacyOpt = Annotated[bool, typer.Option("--legacy", help="Board printed by OpenCV < 4.6 (legacy ChArUco pattern).")]
SeedOpt = Annotated[int, typer.Option("--seed", help="Seed of the station generator (and sim noise).")]


def _board(squares: str, square_mm: float, marker_mm: float, dictionary: str, legacy: bool):
    from calibration.board import BoardConfig
    from deploy.errors import ConfigError

    try:
        cols, rows = (int(v) for v in squares.lower().split("x"))
    except ValueError as exc:
        raise ConfigError(f"--squares {squares!r} is not COLSxROWS: write e.g. 5x7") from exc
    return BoardConfig((cols, rows), square_mm / 1000, marker_mm / 1000, dictionary, legacy)


def _require_sim(camera: str, arm: str) -> None:
    from deploy.errors import ConfigError

    if camera != "sim" or arm != "sim":
        raise ConfigError(
            f"--camera {camera} --arm {arm}: only the simulated rig (--camera sim --arm sim) is wired to calibration "
            "yet; real cameras and arms arrive with their factories (drivers/camera, drivers/arm)"
        )


def register(app: typer.Typer, bench_app: typer.Typer) -> None:
    """Add this area's commands to the main app and to `deploy bench`."""
    from deploy.cli import _print_json, console, err_console

    calibrate_app = typer.Typer(help="Field calibration: ChArUco board, intrinsics, hand-eye, checks.",
                                no_args_is_help=True)
    app.add_typer(calibrate_app, name="calibrate")

    def _table(title: str, rows: dict) -> None:
        from rich.table import Table

        table = Table(title=title, show_header=False)
        for key, value in rows.items():
            table.add_row(key, f"{value:.4f}" if isinstance(value, float) else str(value))
        console.print(table)

    def _progress(label: str):
        from rich.progress import Progress

        bar = Progress(console=err_console, transient=True)
        job = bar.add_task(label, total=None)
        return bar, lambda done, total: bar.update(job, completed=done, total=total)

    @calibrate_app.command("board")
    def board_cmd(
        out: Annotated[Path, typer.Option("--out", help="PNG or PDF to write (true scale).")] = Path("board.pdf"),
        squares: SquaresOpt = "5x7", square_mm: SquareMmOpt = 38.0, marker_mm: MarkerMmOpt = 28.0,
        dictionary: DictOpt = "DICT_4X4_50", legacy: LegacyOpt = False,
        dpi: Annotated[float, typer.Option("--dpi", min=72.0, help="Print resolution.")] = 300.0,
    ) -> None:
        """Render a printable ChArUco board at true scale: print at 100 %, then measure one square.

        Example: deploy calibrate board --out board.pdf --squares 5x7 --square-mm 38 --marker-mm 28
        """
        from calibration.board import write_board

        cfg = _board(squares, square_mm, marker_mm, dictionary, legacy)
        write_board(cfg, out, dpi)
        w, h = cfg.size_m
        console.print(f"wrote {out}: {squares} squares of {square_mm:g} mm ({w * 1e3:.0f} x {h * 1e3:.0f} mm)")

    @calibrate_app.command("intrinsics")
    def intrinsics_cmd(
        camera: CameraOpt = "sim", arm: ArmOpt = "sim", poses: PosesOpt = 12, setup: SetupOpt = SetupChoice.eye_to_hand,
        squares: SquaresOpt = "5x7", square_mm: SquareMmOpt = 38.0, marker_mm: MarkerMmOpt = 28.0,
        dictionary: DictOpt = "DICT_4X4_50", legacy: LegacyOpt = False, directory: DirOpt = None,
        seed: SeedOpt = 0, json_out: JsonOpt = False,
    ) -> None:
        """Fit the camera's own intrinsics from board views at N stations (default: RealSense factory values).

        Example: deploy calibrate intrinsics --poses 12 --json
        """
        from calibration.routine import run_intrinsics
        from calibration.store import IntrinsicsRecord, save_intrinsics
        from deploy.bench.calibration import limits, routine_config, sim_rig

        _require_sim(camera, arm)
        board = _board(squares, square_mm, marker_mm, dictionary, legacy)
        bar, progress = _progress("intrinsics")
        with sim_rig(setup.value, board, seed=seed) as rig, bar:
            result = run_intrinsics(rig.camera, rig.arm, rig.arm.kin, routine_config(rig, poses, board, seed),
                                    limits(rig), progress)
            factory = rig.camera.intrinsics
        path = save_intrinsics(IntrinsicsRecord(SIM_SERIAL, result.intrinsics, result.distortion, result.rms_px,
                                                result.views), directory)
        data = {"file": str(path), "views": result.views, "rms_px": result.rms_px, **result.intrinsics.to_dict(),
                "distortion": result.distortion.tolist(), "factory": factory.to_dict()}
        if json_out:
            _print_json(data)
        else:
            _table(f"intrinsics of {SIM_SERIAL}", {k: v for k, v in data.items() if k not in ("factory",)})

    @calibrate_app.command("hand-eye")
    def hand_eye_cmd(
        setup: SetupOpt = SetupChoice.eye_to_hand, poses: PosesOpt = 15, camera: CameraOpt = "sim", arm: ArmOpt = "sim",
        robot_id: RobotIdOpt = "panda", squares: SquaresOpt = "5x7", square_mm: SquareMmOpt = 38.0,
        marker_mm: MarkerMmOpt = 28.0, dictionary: DictOpt = "DICT_4X4_50", legacy: LegacyOpt = False,
        existing: Annotated[ExistingChoice, typer.Option("--existing", help="When a calibration exists: ask, reuse "
                                                         "it, or redo it.")] = ExistingChoice.ask,
        directory: DirOpt = None, seed: SeedOpt = 0, json_out: JsonOpt = False,
    ) -> None:
        """Hand-eye: move through N diverse poses, detect the board, solve, refine and save the calibration.

        Several solvers run; the most consistent one is refined on the corners' reprojection error. The file is
        one per camera serial and robot id; an existing one is offered for reuse first.

        Example: deploy calibrate hand-eye --setup eye-to-hand --poses 15 --json
        """
        from calibration.store import hand_eye_path, load_for, load_intrinsics_for
        from deploy.bench.calibration import sim_rig, simulated_hand_eye

        _require_sim(camera, arm)
        board = _board(squares, square_mm, marker_mm, dictionary, legacy)
        old = load_for(SIM_SERIAL, robot_id, directory) if existing != ExistingChoice.redo else None
        if old is not None and (existing == ExistingChoice.reuse or typer.confirm(
                f"{hand_eye_path(SIM_SERIAL, robot_id, directory)} exists ({old.setup}, {old.method}, "
                f"{old.created:%Y-%m-%d}, spread {old.spread_mm:.1f} mm): reuse it?", default=True,
                err=True)):
            data = {"file": str(hand_eye_path(SIM_SERIAL, robot_id, directory)), "reused": True}
            if json_out:
                _print_json(data)
            else:
                console.print(f"reusing {data['file']}")
            return
        own = load_intrinsics_for(SIM_SERIAL, directory)  # else the camera's factory values
        bar, progress = _progress(f"hand-eye {setup.value}")
        with sim_rig(setup.value, board, seed=seed) as rig, bar:
            run, (err_mm, err_deg) = simulated_hand_eye(rig, poses, board, seed, own and own.intrinsics,
                                                        own and own.distortion, progress)
            path = _save(run, rig, board, robot_id, directory)
        data = _hand_eye_summary(run, path) | {"true_error_mm": err_mm, "true_error_deg": err_deg}
        if json_out:
            _print_json(data)
        else:
            _table(f"hand-eye {setup.value} ({SIM_SERIAL} on {robot_id})", {k: v for k, v in data.items()
                                                                           if k != "methods"})

    @calibrate_app.command("check")
    def check_cmd(
        camera: CameraOpt = "sim", arm: ArmOpt = "sim", robot_id: RobotIdOpt = "panda", poses: PosesOpt = 6,
        max_age_days: Annotated[float, typer.Option("--max-age-days", help="Warn when older.")] = 30.0,
        point: Annotated[bool, typer.Option("--point", help="Eye-in-hand: move the tool tip to 2 cm in front of "
                                            "the board's centre corner.")] = False,
        directory: DirOpt = None, seed: SeedOpt = 1, json_out: JsonOpt = False,
    ) -> None:
        """Check the stored calibration: spread of the fixed frame over fresh poses, a one-shot test, warnings.

        Example: deploy calibrate check --poses 6 --json
        """
        import numpy as np

        from calibration.routine import point_at_board, run_check
        from calibration.store import load_for
        from deploy.bench.calibration import limits, routine_config, sim_rig
        from deploy.errors import CalibrationError

        _require_sim(camera, arm)
        record = load_for(SIM_SERIAL, robot_id, directory)
        if record is None:
            raise CalibrationError(f"no hand-eye calibration for camera {SIM_SERIAL} on robot {robot_id}: run "
                                   "`deploy calibrate hand-eye` first")
        bar, progress = _progress("check")
        with sim_rig(record.setup, record.board, seed=seed) as rig, bar:
            report = run_check(rig.camera, rig.arm, rig.arm.kin, record, routine_config(rig, poses, record.board, seed),
                               limits(rig), SIM_SERIAL, max_age_days, progress)
            data = report.to_dict()
            if point:
                pointed = point_at_board(rig.camera, rig.arm, rig.arm.kin, record, limits(rig))
                data |= {"point_corner_m": pointed.corner.tolist(), "point_reached_m": pointed.reached.tolist(),
                         "point_tracking_mm": float(np.linalg.norm(pointed.reached - pointed.target) * 1e3),
                         "point_true_error_mm": float(np.linalg.norm(pointed.corner - _true_corner(rig, record.board))
                                                      * 1e3)}
        for warning in report.warnings:
            err_console.print(f"[yellow]warning:[/] {warning}", highlight=False)
        if json_out:
            _print_json(data)
        else:
            _table(f"check of {record.setup} calibration ({record.created:%Y-%m-%d})", data)

    @bench_app.command("calibration")
    def bench_calibration_cmd(seed: SeedOpt = 0, json_out: JsonOpt = False) -> None:
        """Hand-eye error against simulated truth vs number of poses, depth/colour noise and method (640x480).

        Example: deploy bench calibration --json
        """
        from rich.table import Table

        from deploy.bench.calibration import bench_calibration

        with err_console.status("bench calibration") as status:
            data = bench_calibration(seed=seed, progress=lambda what: status.update(f"bench calibration: {what}"))
        if json_out:
            _print_json(data)
            return
        table = Table(title="hand-eye error vs truth (mm / deg), simulated D415 at 640x480")
        for col in ("setup", "noise", "method", "poses", "mm", "deg"):
            table.add_column(col)
        for r in data["results"]:
            table.add_row(r["setup"], r["noise"], r["method"], str(r["poses"]), f"{r['translation_mm']:.2f}",
                          f"{r['rotation_deg']:.3f}")
        console.print(table)
        console.print(f"best at 15 poses: {data['best_at_15_poses']}")


def _save(run, rig, board, robot_id: str, directory: Path | None) -> Path:
    """The run's best solution as this camera and robot's calibration file."""
    from calibration.store import HandEyeRecord, save_hand_eye

    best = run.best
    record = HandEyeRecord(
        camera_serial=SIM_SERIAL, robot_id=robot_id, setup=best.setup,
        method=best.method + ("+refined" if best.refined else ""), T_camera=best.T_camera, T_board=best.T_board,
        tool_frame=rig.arm.kin.tool_frame, intrinsics=run.intrinsics, distortion=run.distortion,
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
