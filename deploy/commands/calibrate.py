"""`deploy calibrate board|intrinsics|hand-eye|check`: ChArUco board, intrinsics, hand-eye and its check."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from enum import Enum
from pathlib import Path
from typing import Annotated, Any

import typer

from deploy.commands.options import (
    BitrateOpt,
    ChannelOpt,
    DataBitrateOpt,
    InterfaceOpt,
    JsonOpt,
    SimFaultOpt,
    StationSeedOpt,
    above,
    can_settings,
    dry_run_option,
    kind_option,
    overwrite_option,
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
OverwriteOpt = overwrite_option("board file at --out")
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
    squares: SquaresOpt = "5x7", square_mm: SquareMmOpt = 36.0, marker_mm: MarkerMmOpt = 27.0,
    dictionary: DictOpt = "DICT_4X4_50", legacy: LegacyOpt = False,
    dpi: Annotated[float, typer.Option("--dpi", min=72.0, help="Print resolution.")] = 300.0,
    overwrite: OverwriteOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Render a printable ChArUco board at true scale, its parameters printed under it, on a page that A4 and
    Letter both hold (when the board fits): print at 100 %, then measure one square.

    Example: deploy calibrate board --out board.pdf --squares 5x7 --square-mm 36 --marker-mm 27
    """
    from calibration.board import fits_a4_and_letter, page_m, write_board

    cfg = _board(squares, square_mm, marker_mm, dictionary, legacy)
    write_board(cfg, out, dpi, overwrite=overwrite)
    (w, h), page = cfg.size_m, page_m(cfg)
    fits = fits_a4_and_letter(cfg)
    if json_out:
        print_json({"out": str(out), "squares": squares, "square_mm": square_mm, "marker_mm": marker_mm,
                    "dictionary": dictionary, "width_mm": w * 1e3, "height_mm": h * 1e3, "dpi": dpi,
                    "page_mm": [round(v * 1e3, 1) for v in page], "fits_a4_and_letter": fits})
    else:
        paper = "fits A4 and Letter" if fits else f"needs a {page[0] * 1e3:.0f} x {page[1] * 1e3:.0f} mm sheet"
        console.print(f"wrote {out}: {squares} squares of {square_mm:g} mm ({w * 1e3:.0f} x {h * 1e3:.0f} mm; the "
                      f"page {paper})")


def _ask(yes: bool) -> Any:
    """How the workflow asks: reuse a file (--existing ask: a question, default yes), confirm a real arm's motion
    (unless --yes), progress bars."""
    from deploy.calibration_workflow import Ask

    def confirm(message: str) -> None:
        typer.confirm(message, abort=True, err=True)

    @contextmanager
    def progress(label: str) -> Iterator[Any]:
        with progress_bar(label) as bar:
            yield bar.counts

    return Ask(_reuse_answer, None if yes else confirm, progress)


def _reuse_answer(path: Path, about: str) -> bool:
    """The user's answer to reusing the file at `path` (default yes); ConfigError naming --existing when standard
    input is closed and nobody can answer."""
    from deploy.errors import ConfigError

    try:
        return typer.confirm(f"{path} exists ({about}): reuse it?", default=True, err=True)
    except typer.Abort as exc:
        if not isinstance(exc.__context__, EOFError):
            raise
        typer.echo(err=True)  # end the question's line
        raise ConfigError(f"{path} exists and standard input is closed, so whether to reuse it cannot be asked: "
                          "pass --existing reuse or --existing redo") from exc


def _request(camera: str, arm: str | None, robot: Path | None, pivot_mm, sim_fault: list[str] | None, board,
             poses: int, seed: int, setup: str | None, existing: ExistingChoice, directory: Path | None,
             dry_run: bool, pivot_from_record: bool = False, can: tuple = ()) -> Any:
    """The workflow's request from the options: devices checked (deploy.calibration_devices.choose), faults parsed."""
    from deploy.arm_bringup import parse_sim_faults
    from deploy.calibration_devices import choose
    from deploy.calibration_workflow import Request

    choice = choose(camera, arm, robot, pivot_mm, pivot_from_record, can)
    return Request(choice, board, poses, seed, setup, existing.value, directory, dry_run,
                   parse_sim_faults(choice.arm, sim_fault))


def _show(outcome: Any, json_out: bool, keep: tuple[str, ...] = ()) -> None:
    """Print a workflow's outcome: JSON, the reused file, the dry run's stations, or its rows (`keep` of its keys
    only in the JSON)."""
    for warning in outcome.warnings:
        err_console.print(f"[yellow]warning:[/] {warning}", highlight=False)
    if json_out:
        print_json(outcome.data)
    elif outcome.status == "reused":
        console.print(f"reusing {outcome.data['file']}")
    elif outcome.status == "dry run":
        plan, data = outcome.plan, outcome.data
        print_table(outcome.title, ("#", "joints (rad)", "tool position (m)", "turn (deg)"),
                    [(str(i + 1), " ".join(f"{v:+.3f}" for v in s["q"]),
                      " ".join(f"{v:.3f}" for v in s["tool_position_m"]), f"{s['turn_deg']:.1f}")
                     for i, s in enumerate(data["stations"])])
        console.print(f"board visible at the start pose: {data['board_visible']}; about {plan.duration_s:.0f} s; "
                      f"tool within {plan.max_shift_m * 100:.1f} cm and {plan.max_turn_deg:.1f} deg of its start")
    else:
        print_rows(outcome.title, {k: v for k, v in outcome.data.items() if k not in keep}, digits=4)


@app.command("intrinsics")
def intrinsics_cmd(
    camera: CameraOpt = "sim", arm: ArmOpt = None, robot: RobotOpt = None, pivot_mm: PivotOpt = None,
    poses: PosesOpt = 12, setup: SetupOpt = SetupChoice.eye_to_hand,
    squares: SquaresOpt = "5x7", square_mm: SquareMmOpt = 36.0, marker_mm: MarkerMmOpt = 27.0,
    dictionary: DictOpt = "DICT_4X4_50", legacy: LegacyOpt = False, existing: ExistingOpt = ExistingChoice.ask,
    directory: DirOpt = None, yes: YesOpt = False, dry_run: DryRunOpt = False, seed: StationSeedOpt = 0,
    interface: InterfaceOpt = None, channel: ChannelOpt = None, bitrate: BitrateOpt = None,
    data_bitrate: DataBitrateOpt = None, sim_fault: SimFaultOpt = None, json_out: JsonOpt = False,
) -> None:
    """Fit the camera's own intrinsics from board views at N stations (default: RealSense factory values).

    The fit is saved (and hand-eye uses it) only when it is precise and differs significantly from the factory
    values; one that confirms them saves nothing; an unreliable or implausible one is refused.

    Example: deploy calibrate intrinsics --camera d415 --arm can --robot my_arm.toml --pivot-mm 0 0 30 --poses 12
    """
    from calibration.intrinsics import SIGNIFICANT_SIGMAS
    from calibration.routine import check_poses
    from deploy.calibration_workflow import intrinsics

    check_poses("intrinsics", poses)
    board = _board(squares, square_mm, marker_mm, dictionary, legacy)
    request = _request(camera, arm, robot, pivot_mm, sim_fault, board, poses, seed, setup.value, existing, directory,
                       dry_run, can=can_settings(interface, channel, bitrate, data_bitrate))
    outcome = intrinsics(request, _ask(yes))
    _show(outcome, json_out, keep=("factory", "std"))
    if json_out or outcome.status != "done":
        return
    data = outcome.data
    if data["saved"]:
        console.print(f"saved {data['file']}: they differ from the factory values by more than "
                      f"{SIGNIFICANT_SIGMAS:g} sigma; hand-eye uses them from now on")
    else:
        removed = f" (removed the old {outcome.path})" if data["removed_old_file"] else ""
        console.print(f"the fit agrees with the factory values within {SIGNIFICANT_SIGMAS:g} sigma: nothing saved, "
                      f"hand-eye uses the factory values{removed}")


@app.command("hand-eye")
def hand_eye_cmd(
    setup: HandEyeSetupOpt = None, poses: PosesOpt = 15, camera: CameraOpt = "sim", arm: ArmOpt = None,
    robot: RobotOpt = None, pivot_mm: PivotOpt = None, squares: SquaresOpt = "5x7", square_mm: SquareMmOpt = 36.0,
    marker_mm: MarkerMmOpt = 28.0, dictionary: DictOpt = "DICT_4X4_50", legacy: LegacyOpt = False,
    existing: ExistingOpt = ExistingChoice.ask,
    directory: DirOpt = None, yes: YesOpt = False, dry_run: DryRunOpt = False, seed: StationSeedOpt = 0,
    interface: InterfaceOpt = None, channel: ChannelOpt = None, bitrate: BitrateOpt = None,
    data_bitrate: DataBitrateOpt = None, sim_fault: SimFaultOpt = None, json_out: JsonOpt = False,
) -> None:
    """Hand-eye: move through N diverse poses, detect the board, solve, refine and save the calibration.

    Several solvers run; the most consistent one is refined on the corners' reprojection error. The file is
    one per camera serial and robot config name; an existing one is offered for reuse first (--existing reuse|redo
    answers in advance; a file of another --setup is never reused). A real arm asks before it moves (--yes
    skips); --dry-run prints the stations and moves nothing.

    Example: deploy calibrate hand-eye --camera d415 --arm can --robot my_arm.toml --pivot-mm 0 0 30 --poses 15
    """
    from calibration.routine import check_poses
    from deploy.calibration_workflow import hand_eye

    check_poses("hand-eye", poses)
    board = _board(squares, square_mm, marker_mm, dictionary, legacy)
    request = _request(camera, arm, robot, pivot_mm, sim_fault, board, poses, seed, setup and setup.value, existing,
                       directory, dry_run, can=can_settings(interface, channel, bitrate, data_bitrate))
    _show(hand_eye(request, _ask(yes)), json_out, keep=("methods",))


@app.command("check")
def check_cmd(
    camera: CameraOpt = "sim", arm: ArmOpt = None, robot: RobotOpt = None, pivot_mm: PivotOpt = None,
    poses: PosesOpt = 6,
    max_age_days: Annotated[float, typer.Option("--max-age-days", callback=above(0.0), help="Warn when older.")
                            ] = 30.0,
    point: Annotated[bool, typer.Option("--point", help="Eye-in-hand: move the tool tip to 2 cm in front of "
                                        "the board's centre corner.")] = False,
    directory: DirOpt = None, yes: YesOpt = False, dry_run: DryRunOpt = False, seed: StationSeedOpt = 1,
    interface: InterfaceOpt = None, channel: ChannelOpt = None, bitrate: BitrateOpt = None,
    data_bitrate: DataBitrateOpt = None, sim_fault: SimFaultOpt = None, json_out: JsonOpt = False,
) -> None:
    """Check the stored calibration: spread of the fixed frame over fresh poses, a one-shot test, warnings.

    Example: deploy calibrate check --camera d415 --arm can --robot my_arm.toml --poses 6 --json
    """
    from calibration.board import BoardConfig
    from calibration.routine import check_poses
    from deploy.calibration_workflow import check

    check_poses("check", poses)
    request = _request(camera, arm, robot, pivot_mm, sim_fault, BoardConfig(), poses, seed, None,
                       ExistingChoice.reuse, directory, dry_run, pivot_from_record=True,
                       can=can_settings(interface, channel, bitrate, data_bitrate))
    _show(check(request, _ask(yes), max_age_days, point), json_out)
