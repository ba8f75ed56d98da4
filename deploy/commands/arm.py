"""`deploy arm scan|status|enable|disable|zero|home|jog|move`: bring-up of a CAN (or simulated) arm."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from deploy.commands.options import ArmOpt, JsonOpt, RobotOpt, dry_run_option, yes_option
from deploy.commands.output import console, err_console, print_json, print_rows, print_table, progress_bar

app = typer.Typer(help="Arm bring-up: scan the CAN bus, status, enable/disable/zero, home, jog, move.",
                  no_args_is_help=True)


YesOpt = yes_option("Do not ask before moving.")
DryRunOpt = dry_run_option("Plan and print the move; enable nothing.")
HoldOpt = Annotated[float, typer.Option("--hold", help="Seconds to hold the goal before damping and disabling.")]


def _print_motors(title: str, motors: list[dict]) -> None:
    keys = [k for k in ("name", "can_id", "master_id", "status", "q", "tau", "t_mos_c", "p_max", "v_max", "t_max")
            if motors and k in motors[0]]
    print_table(title, keys, [[f"{m[k]:.2f}" if isinstance(m[k], float) else str(m[k]) for k in keys]
                              for m in motors])


@app.command("scan")
def scan_cmd(
    arm: ArmOpt = "sim-can",
    robot: RobotOpt = None,
    first_id: Annotated[int, typer.Option(help="First CAN id to try.")] = 1,
    last_id: Annotated[int, typer.Option(help="Last CAN id to try.")] = 16,
    json_out: JsonOpt = False,
) -> None:
    """List the motors that answer on the bus: CAN id, master id, status and PMAX/VMAX/TMAX (enables nothing).

    Example: deploy arm scan --arm can --robot configs/robots/damiao_6dof.toml --json
    """
    from deploy.arm_bringup import load, scan

    motors = scan(arm, load(robot), range(first_id, last_id + 1))
    if json_out:
        print_json({"motors": motors})
    elif motors:
        _print_motors(f"motors answering on ids {first_id}..{last_id}", motors)
    else:
        err_console.print(f"no motor answered on ids {first_id}..{last_id}: check power, wiring and bitrate")
    if not motors:
        raise typer.Exit(1)


@app.command("status")
def status_cmd(arm: ArmOpt = "sim-can", robot: RobotOpt = None, json_out: JsonOpt = False) -> None:
    """Joint positions, tool pose and each motor's status, temperatures and limits (enables the motors
    briefly, holding their position, then damps and disables them).

    Example: deploy arm status --arm sim-can --json
    """
    from deploy.arm_bringup import load, make_arm, status

    data = status(make_arm(arm, load(robot)))
    if json_out:
        print_json(data)
        return
    print_rows("arm", {k: v for k, v in data.items() if k != "motors"}, digits=None)
    if "motors" in data:
        _print_motors("motors", data["motors"])


@app.command("enable")
def enable_cmd(
    arm: ArmOpt = "sim-can",
    robot: RobotOpt = None,
    clear_errors: Annotated[bool, typer.Option(help="Send clear-error to every motor first.")] = False,
    hold: Annotated[float, typer.Option(help="Seconds to hold position (Ctrl-C stops earlier).")] = 5.0,
    yes: YesOpt = False,
) -> None:
    """Enable the motors and hold the current position for --hold seconds, then damp and disable.

    Example: deploy arm enable --arm can --robot my_arm.toml --clear-errors --hold 30
    """
    import time

    from deploy.arm_bringup import load, make_arm
    from drivers.arm.can_arm import CanArm

    a = make_arm(arm, load(robot))
    if not yes and not typer.confirm(f"Enable the motors of the {arm} arm and hold position?"):
        raise typer.Exit(1)
    if clear_errors and isinstance(a, CanArm):
        a.clear_errors()
    with a:
        console.print(f"enabled; holding for {hold:.1f} s (Ctrl-C to stop)")
        end = time.perf_counter() + hold
        while time.perf_counter() < end:
            a.sync()
    console.print("damped and disabled")


@app.command("disable")
def disable_cmd(arm: ArmOpt = "sim-can", robot: RobotOpt = None) -> None:
    """Disable every configured motor at once (the arm goes limp: support it first).

    Example: deploy arm disable --arm can --robot my_arm.toml
    """
    from deploy.arm_bringup import disable_all, load

    console.print(f"sent disable to {disable_all(load(robot), arm)} motors")


@app.command("zero")
def zero_cmd(
    joint: Annotated[str, typer.Option("--joint", help="Joint name (or `gripper`) whose motor is zeroed.")],
    arm: ArmOpt = "sim-can",
    robot: RobotOpt = None,
    yes: YesOpt = False,
) -> None:
    """Make a motor's current position its zero (disables it first). Put the joint at the pose where
    the config's zero_offset says the motor reads 0.

    Example: deploy arm zero --joint joint2 --arm can --robot my_arm.toml
    """
    from deploy.arm_bringup import load, set_zero

    if not yes and not typer.confirm(f"Set the zero of {joint}'s motor at its current position?"):
        raise typer.Exit(1)
    print_json(set_zero(load(robot), arm, joint))


def _move(kind: str, robot: Path | None, what: str, dry_run: bool, yes: bool, hold: float, json_out: bool,
          **target) -> None:
    """Plan `what` (home, jog or move) from the measured joints, show it, ask, then run it."""
    from deploy.arm_bringup import execute, load, make_arm, plan
    from drivers.arm.can_arm import CanArm

    config = load(robot)
    a = make_arm(kind, config)
    try:
        if isinstance(a, CanArm):
            a.probe()  # measured joints without enabling
        p = plan(a, config, what, **target)
    except BaseException:
        a.disconnect()
        raise
    if json_out and dry_run:
        print_json({"dry_run": True, **p.to_dict()})
    elif not json_out:
        print_rows(f"{what} plan ({kind} arm{', dry run' if dry_run else ''})", p.to_dict(), digits=None)
    if dry_run or (not yes and not typer.confirm("Run this motion now?")):
        a.disconnect()
        if not dry_run:
            raise typer.Exit(1)
        return
    with a, progress_bar(what, 1.0) as bar:
        result = execute(a, config, p, hold, progress=bar.completed)
    if json_out:
        print_json({"dry_run": False, **p.to_dict(), **result})
    else:
        print_rows(f"{what} done", result, digits=None)


@app.command("home")
def home_cmd(arm: ArmOpt = "sim-can", robot: RobotOpt = None, dry_run: DryRunOpt = False,
             yes: YesOpt = False, hold: HoldOpt = 0.0, json_out: JsonOpt = False) -> None:
    """Move to the config's ready pose (q_ready) slowly, after showing the plan and asking.

    Example: deploy arm home --arm can --robot my_arm.toml --dry-run
    """
    _move(arm, robot, "home", dry_run, yes, hold, json_out)


@app.command("jog")
def jog_cmd(
    joint: Annotated[str, typer.Option("--joint", help="Joint name.")],
    delta: Annotated[float, typer.Option("--delta", help="Joint change (rad or m).")],
    arm: ArmOpt = "sim-can",
    robot: RobotOpt = None,
    dry_run: DryRunOpt = False,
    yes: YesOpt = False,
    hold: HoldOpt = 0.0,
    json_out: JsonOpt = False,
) -> None:
    """Move one joint by --delta (check each joint's direction sign this way, with small deltas first).

    Example: deploy arm jog --joint panda_joint1 --delta 0.1 --yes
    """
    _move(arm, robot, "jog", dry_run, yes, hold, json_out, joint=joint, delta=delta)


@app.command("move")
def move_cmd(
    pose: Annotated[tuple[float, float, float, float, float, float], typer.Option(
        "--pose", help="Tool pose: x y z (m, base frame) roll pitch yaw (deg, xyz Euler).")],
    arm: ArmOpt = "sim-can",
    robot: RobotOpt = None,
    dry_run: DryRunOpt = False,
    yes: YesOpt = False,
    hold: HoldOpt = 0.0,
    json_out: JsonOpt = False,
) -> None:
    """Move the tool to a pose (IK, then a jerk-limited joint move; no collision check).

    Example: deploy arm move --pose 0.45 0.0 0.6 0 90 0 --dry-run
    """
    _move(arm, robot, "move", dry_run, yes, hold, json_out, pose=pose)
