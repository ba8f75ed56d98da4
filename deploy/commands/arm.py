"""`deploy arm scan|status|enable|disable|zero|home|jog|move`: bring-up of a CAN (or simulated) arm."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from deploy.commands.options import (
    ArmOpt,
    BitrateOpt,
    ChannelOpt,
    DataBitrateOpt,
    InterfaceOpt,
    JsonOpt,
    RobotOpt,
    SimFaultOpt,
    can_settings,
    dry_run_option,
    yes_option,
)
from deploy.commands.output import console, err_console, print_json, print_rows, print_table, progress_bar

app = typer.Typer(help="Arm bring-up: scan the CAN bus, status, enable/disable/zero, home, jog, move.",
                  no_args_is_help=True)


YesOpt = yes_option("Do not ask before moving.")
DryRunOpt = dry_run_option("Plan and print the move; enable nothing.")
HoldOpt = Annotated[float, typer.Option("--hold", min=0.0,
                                        help="Seconds to hold the goal before damping and disabling.")]


SCAN_KEYS = ("can_id", "master_id", "status", "p_max", "v_max", "t_max", "timeout_ms", "fd")
STATUS_KEYS = ("name", "can_id", "status", "q", "tau", "t_mos_c", "timeout_ms")  # the rest: --json


def _print_motors(title: str, motors: list[dict], keys: tuple[str, ...]) -> None:
    keys = [k for k in keys if motors and k in motors[0]]
    print_table(title, keys, [[f"{m[k]:.2f}" if isinstance(m[k], float) else str(m[k]) for k in keys]
                              for m in motors])


def _print_plan_to_stderr(title: str, rows: dict) -> None:
    from rich.table import Table

    table = Table(title=title, show_header=False)
    for key, value in rows.items():
        table.add_row(key, str(value))
    err_console.print(table)


@app.command("scan")
def scan_cmd(
    arm: ArmOpt = "sim-can",
    robot: RobotOpt = None,
    first_id: Annotated[int, typer.Option(min=1, max=0x7FE, help="First CAN id to try (1 .. 2046).")] = 1,
    last_id: Annotated[int, typer.Option(min=1, max=0x7FE, help="Last CAN id to try (1 .. 2046).")] = 16,
    interface: InterfaceOpt = None,
    channel: ChannelOpt = None,
    bitrate: BitrateOpt = None,
    data_bitrate: DataBitrateOpt = None,
    sim_fault: SimFaultOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """List the motors that answer on the bus: CAN id, master id, status and PMAX/VMAX/TMAX (enables nothing).

    Example: deploy arm scan --arm can --robot my_arm.toml --json
    """
    from deploy.arm_bringup import parse_sim_faults, scan
    from deploy.errors import ConfigError
    from deploy.rig import load_robot

    if last_id < first_id:
        raise ConfigError(f"--last-id {last_id} is below --first-id {first_id}: give a range first .. last")
    config = load_robot(arm, robot, can_settings(interface, channel, bitrate, data_bitrate))
    motors = scan(arm, config, range(first_id, last_id + 1), parse_sim_faults(arm, sim_fault))
    if json_out:
        print_json({"motors": motors})
    elif motors:
        _print_motors(f"motors answering on ids {first_id}..{last_id}", motors, SCAN_KEYS)
    else:
        err_console.print(f"no motor answered on ids {first_id}..{last_id}: check power, wiring and bitrate")
    if not motors:
        raise typer.Exit(1)


@app.command("status")
def status_cmd(arm: ArmOpt = "sim-can", robot: RobotOpt = None, interface: InterfaceOpt = None,
               channel: ChannelOpt = None, bitrate: BitrateOpt = None, data_bitrate: DataBitrateOpt = None,
               sim_fault: SimFaultOpt = None, json_out: JsonOpt = False) -> None:
    """Joint positions, tool pose and each motor's status, temperatures and limits (enables the motors
    briefly, holding their position, then damps and disables them).

    Example: deploy arm status --arm sim-can --json
    """
    from deploy.arm_bringup import inject_sim_faults, make_arm, parse_sim_faults, released, status
    from deploy.rig import load_robot
    from drivers.arm.disable import disable_summary

    faults = parse_sim_faults(arm, sim_fault)
    a = make_arm(arm, load_robot(arm, robot, can_settings(interface, channel, bitrate, data_bitrate)))
    with released(a):
        inject_sim_faults(a, faults)
    data = status(a)
    after = data.get("motors_after_stop", [])
    if json_out:
        print_json(data)
    else:
        print_rows("arm", {k: v for k, v in data.items() if not k.startswith("motors")}, digits=None)
        if after:
            _print_motors("motors (while enabled)", data["motors"], STATUS_KEYS)
            console.print(f"then damped; {disable_summary(after)}")
    if any(m["enabled"] for m in after):  # a motor did not confirm the disable: it may still be enabled
        raise typer.Exit(1)


@app.command("enable")
def enable_cmd(
    arm: ArmOpt = "sim-can",
    robot: RobotOpt = None,
    clear_errors: Annotated[bool, typer.Option(help="Send clear-error to every motor first.")] = False,
    hold: Annotated[float, typer.Option(min=0.0, help="Seconds to hold position (Ctrl-C stops earlier).")] = 5.0,
    yes: YesOpt = False,
    interface: InterfaceOpt = None,
    channel: ChannelOpt = None,
    bitrate: BitrateOpt = None,
    data_bitrate: DataBitrateOpt = None,
    sim_fault: SimFaultOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Enable the motors and hold the current position for --hold seconds, then damp and disable.

    Example: deploy arm enable --arm can --robot my_arm.toml --clear-errors --hold 30
    """
    import time

    from deploy.arm_bringup import inject_sim_faults, make_arm, parse_sim_faults, released
    from deploy.rig import load_robot
    from drivers.arm.disable import disable_summary

    faults = parse_sim_faults(arm, sim_fault)
    a = make_arm(arm, load_robot(arm, robot, can_settings(interface, channel, bitrate, data_bitrate)))
    with released(a):
        inject_sim_faults(a, faults)
        if not yes and not typer.confirm(f"Enable the motors of the {arm} arm and hold position?", err=json_out):
            a.disconnect()
            raise typer.Exit(1)
        if clear_errors:
            a.clear_errors()
    with a:
        (err_console if json_out else console).print(f"enabled; holding for {hold:.1f} s (Ctrl-C to stop)")
        end = time.perf_counter() + hold
        while time.perf_counter() < end:
            a.sync()
    states = a.motor_states()
    if json_out:
        print_json({"held_s": hold, "motors": states})
    else:
        console.print(f"damped; {disable_summary(states)}" if states else "damped and disabled")


@app.command("disable")
def disable_cmd(arm: ArmOpt = "sim-can", robot: RobotOpt = None, interface: InterfaceOpt = None,
                channel: ChannelOpt = None, bitrate: BitrateOpt = None, data_bitrate: DataBitrateOpt = None,
                sim_fault: SimFaultOpt = None, json_out: JsonOpt = False) -> None:
    """Disable every configured motor at once and check each one answers (the arm goes limp: support it first).
    Exits 1 when a motor did not answer.

    Example: deploy arm disable --arm can --robot my_arm.toml
    """
    from deploy.arm_bringup import disable_all, parse_sim_faults
    from deploy.rig import load_robot
    from drivers.arm.disable import disable_summary

    config = load_robot(arm, robot, can_settings(interface, channel, bitrate, data_bitrate))
    states = disable_all(config, arm, parse_sim_faults(arm, sim_fault))
    if json_out:
        print_json({"motors": states})
    else:
        console.print(f"sent disable to {len(states)} motors: {disable_summary(states)}")
    if any(s["enabled"] for s in states):
        raise typer.Exit(1)


@app.command("zero")
def zero_cmd(
    joint: Annotated[str, typer.Option("--joint", help="Joint name (or `gripper`) whose motor is zeroed.")],
    arm: ArmOpt = "sim-can",
    robot: RobotOpt = None,
    yes: YesOpt = False,
    interface: InterfaceOpt = None,
    channel: ChannelOpt = None,
    bitrate: BitrateOpt = None,
    data_bitrate: DataBitrateOpt = None,
    sim_fault: SimFaultOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Make a motor's current position its zero (disables it first). Put the joint at the pose where
    the config's zero_offset says the motor reads 0.

    Example: deploy arm zero --joint joint2 --arm can --robot my_arm.toml
    """
    from deploy.arm_bringup import parse_sim_faults, set_zero
    from deploy.rig import load_robot

    faults = parse_sim_faults(arm, sim_fault)
    config = load_robot(arm, robot, can_settings(interface, channel, bitrate, data_bitrate))
    if not yes and not typer.confirm(f"Set the zero of {joint}'s motor at its current position?", err=json_out):
        raise typer.Exit(1)
    result = set_zero(config, arm, joint, faults)
    if json_out:
        print_json(result)
    else:
        print_rows(f"zero of {joint}", result, digits=None)


def _move(kind: str, robot: Path | None, can: tuple, what: str, dry_run: bool, yes: bool, hold: float,
          json_out: bool, sim_fault: list[str] | None, **target) -> None:
    """Plan `what` (home, jog or move) from the measured joints, show it, ask, then run it; `can`: the command
    line's [can] settings."""
    from deploy.arm_bringup import execute, inject_sim_faults, make_arm, parse_sim_faults, plan, released
    from deploy.rig import load_robot

    faults = parse_sim_faults(kind, sim_fault)
    config = load_robot(kind, robot, can)
    a = make_arm(kind, config)
    with released(a):
        inject_sim_faults(a, faults)
        a.probe()  # measured joints without enabling
        p = plan(a, config, what, **target)
        title = f"{what} plan ({kind} arm{', dry run' if dry_run else ''})"
        if json_out and dry_run:
            print_json({"dry_run": True, **p.to_dict()})
        elif not json_out:
            print_rows(title, p.to_dict(), digits=None)
        elif not yes:  # the JSON goes to stdout after the move: the plan to confirm goes to stderr
            _print_plan_to_stderr(title, p.to_dict())
        go = not dry_run and (yes or typer.confirm("Run this motion now?", err=json_out))
    if not go:
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
def home_cmd(arm: ArmOpt = "sim-can", robot: RobotOpt = None, dry_run: DryRunOpt = False, yes: YesOpt = False,
             hold: HoldOpt = 0.0, interface: InterfaceOpt = None, channel: ChannelOpt = None,
             bitrate: BitrateOpt = None, data_bitrate: DataBitrateOpt = None, sim_fault: SimFaultOpt = None,
             json_out: JsonOpt = False) -> None:
    """Move to the config's ready pose (q_ready) slowly, after showing the plan and asking.

    Example: deploy arm home --arm can --robot my_arm.toml --dry-run
    """
    _move(arm, robot, can_settings(interface, channel, bitrate, data_bitrate), "home", dry_run, yes, hold, json_out,
          sim_fault)


@app.command("jog")
def jog_cmd(
    joint: Annotated[str, typer.Option("--joint", help="Joint name.")],
    delta: Annotated[float, typer.Option("--delta", help="Joint change (rad or m).")],
    arm: ArmOpt = "sim-can",
    robot: RobotOpt = None,
    dry_run: DryRunOpt = False,
    yes: YesOpt = False,
    hold: HoldOpt = 0.0,
    interface: InterfaceOpt = None,
    channel: ChannelOpt = None,
    bitrate: BitrateOpt = None,
    data_bitrate: DataBitrateOpt = None,
    sim_fault: SimFaultOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Move one joint by --delta (check each joint's direction sign this way, with small deltas first).

    Example: deploy arm jog --joint panda_joint1 --delta 0.1 --yes
    """
    _move(arm, robot, can_settings(interface, channel, bitrate, data_bitrate), "jog", dry_run, yes, hold, json_out,
          sim_fault, joint=joint, delta=delta)


@app.command("move")
def move_cmd(
    pose: Annotated[tuple[float, float, float, float, float, float], typer.Option(
        "--pose", help="Tool pose: x y z (m, base frame) roll pitch yaw (deg, xyz Euler).")],
    arm: ArmOpt = "sim-can",
    robot: RobotOpt = None,
    dry_run: DryRunOpt = False,
    yes: YesOpt = False,
    hold: HoldOpt = 0.0,
    interface: InterfaceOpt = None,
    channel: ChannelOpt = None,
    bitrate: BitrateOpt = None,
    data_bitrate: DataBitrateOpt = None,
    sim_fault: SimFaultOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Move the tool to a pose (IK, then a jerk-limited joint move; no collision check).

    Example: deploy arm move --pose 0.45 0.0 0.6 0 90 0 --dry-run
    """
    _move(arm, robot, can_settings(interface, channel, bitrate, data_bitrate), "move", dry_run, yes, hold, json_out,
          sim_fault, pose=pose)


@app.command("find-port")
def find_port_cmd(json_out: JsonOpt = False) -> None:
    """List the CAN interfaces and adapters on this machine: SocketCAN links (state, bitrate, CAN FD), serial
    adapters with their USB ids (Damiao's USB-CAN dongle: --interface damiao), and what python-can detects.

    Example: deploy arm find-port
    """
    from drivers.arm.can_ports import find_ports

    found = find_ports()
    if json_out:
        print_json(found)
        return
    links = found["socketcan"]
    print_table("SocketCAN links", ["name", "kind", "up", "state", "bitrate", "data_bitrate", "fd"],
                [[str(link[k]) for k in ("name", "kind", "up", "state", "bitrate", "data_bitrate", "fd")]
                 for link in links]) if links else console.print("no SocketCAN link (`ip link` shows none)")
    serial = found["serial"]
    print_table("serial adapters", ["device", "usb_id", "adapter", "interface"],
                [[str(a[k] or a.get("product") or "-") if k == "adapter" else str(a[k])
                  for k in ("device", "usb_id", "adapter", "interface")] for a in serial]) \
        if serial else console.print("no serial adapter (/dev/ttyACM*, /dev/ttyUSB*)")
    for config in found["python_can"]:
        console.print(f"python-can: --interface {config['interface']} --channel {config.get('channel')}")
    if not any(found.values()):
        console.print("nothing found: plug the adapter in; docs/arm.md says how to bring each kind up")
