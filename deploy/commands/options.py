"""Options and choices that several `deploy` command groups share, defined once.

An option whose meaning differs per group (what `--camera` accepts, what `--yes` skips) comes from a function
here that takes the group's help, so its flag and type are the same in every group.
"""

from __future__ import annotations

from collections.abc import Callable
from enum import Enum
from pathlib import Path
from typing import Annotated, Any

import typer

from deploy.geometry.estimators.registry import ESTIMATORS
from deploy.perception.registry import SEGMENTERS
from deploy.policies import POLICIES
from drivers.arm.registry import ARMS
from drivers.camera.registry import CAMERAS
from drivers.registry import Registry
from sim_fallback.worlds import SCALES, WORLDS


class JointChoice(str, Enum):
    auto = "auto"
    prismatic = "prismatic"
    revolute = "revolute"


class UpChoice(str, Enum):
    """The world's up axis in a trajectory file's frame, or none."""

    x = "x"
    y = "y"
    z = "z"
    none = "none"


class Task(str, Enum):
    drawer = "drawer"
    door = "door"


class Split(str, Enum):
    train = "train"
    test = "test"


class FilterChoice(str, Enum):
    sim = "sim"
    sparse = "sparse"


PolicyChoice = Enum("PolicyChoice", {name: name for name in POLICIES.names()}, type=str)  # type: ignore[misc]
"""The registered opening policies (deploy/policies.py), as command-line choices."""
WorldChoice = Enum("WorldChoice", {name: name for name in WORLDS}, type=str)  # type: ignore[misc]
"""The simulated worlds (sim_fallback/worlds.py), as command-line choices."""
ScaleChoice = Enum("ScaleChoice", {name: name for name in SCALES}, type=str)  # type: ignore[misc]
"""How furniture models are sized (sim_fallback/worlds.py), as command-line choices."""


def yes_option(help: str) -> Any:
    """`--yes/-y`: skip the confirmation `help` names."""
    return Annotated[bool, typer.Option("--yes", "-y", help=help)]


def dry_run_option(help: str) -> Any:
    """`--dry-run`: do what `help` says and move nothing."""
    return Annotated[bool, typer.Option("--dry-run", help=help)]


def kind_option(registry: Registry, flag: str, note: str = "", optional: bool = False) -> Any:
    """`--camera`, `--arm`, `--segmenter`, `--estimator`: help and shell completion from the kind's registry
    (an unknown name is the registry's one-line error); `note` adds what this group does with it."""
    return Annotated[str | None if optional else str, typer.Option(
        flag, help=f"{registry.help()}.{note}", autocompletion=lambda: registry.names())]


def robot_option(help: str) -> Any:
    """`--robot NAME|PATH`: a shipped robot config's name or a robot config TOML."""
    return Annotated[Path | None, typer.Option("--robot", metavar="NAME|PATH", help=help)]


def view_option(what: str) -> Any:
    """`--view`: show `what` in a rerun viewer (live where a display is) and save it as a .rrd file."""
    return Annotated[bool, typer.Option("--view", help=f"Show {what} in a rerun viewer (live where a display is) "
                                        "and save them as a .rrd file.")]


def seed_option(help: str) -> Any:
    """`--seed N` (N >= 0); `help` says what it seeds."""
    return Annotated[int, typer.Option("--seed", min=0, help=help)]


def above(limit: float) -> Callable[[float | None], float | None]:
    """An option callback that refuses a number at or below `limit` (typer's `min` allows the limit itself)."""

    def check(value: float | None) -> float | None:
        if value is not None and not value > limit:
            raise typer.BadParameter(f"{value:g} is not above {limit:g}")
        return value

    return check


def sim_fault_option() -> Any:
    """`--sim-fault KIND[:JOINT][@SECONDS]` (repeatable): a fault of the simulated CAN arm (--arm sim-can)."""
    return Annotated[list[str] | None, typer.Option(
        "--sim-fault", metavar="KIND[:JOINT][@SECONDS]",
        help="With --arm sim-can: inject a fault to rehearse the safety handling, e.g. bus-off@1.5, "
             "silent:panda_joint2, over-temperature:panda_joint4@0.5 (kinds: docs/reliability.md; default joint: the "
             "first; default time: at once, in arm seconds). Repeatable.")]


def overwrite_option(what: str) -> Any:
    """`--overwrite`: replace an existing `what` (its old files go once the new one is being written)."""
    return Annotated[bool, typer.Option("--overwrite", help=f"Replace an existing {what} (its old files are removed "
                                        "once the new one is being written, and kept if the command fails before); "
                                        "without it an existing one is refused.")]


CAN_PANEL = "CAN bus (over the robot config's \\[can])"
InterfaceOpt = Annotated[str | None, typer.Option(
    "--interface", rich_help_panel=CAN_PANEL, help="python-can interface: socketcan, damiao (Damiao's USB-CAN "
    "dongle: pip install python-can-damiao), slcan, gs_usb, pcan, ... (`deploy arm find-port` lists what is here).")]
ChannelOpt = Annotated[str | None, typer.Option(
    "--channel", rich_help_panel=CAN_PANEL, help="CAN channel: can0, /dev/ttyACM0, ...")]
BitrateOpt = Annotated[int | None, typer.Option(
    "--bitrate", min=1, rich_help_panel=CAN_PANEL, help="Nominal bitrate, bit/s (socketcan: set with `ip link`).")]
DataBitrateOpt = Annotated[int | None, typer.Option(
    "--data-bitrate", min=1, rich_help_panel=CAN_PANEL, help="CAN FD data bitrate, bit/s: turns CAN FD on.")]


def can_settings(interface: str | None, channel: str | None, bitrate: int | None,
                 data_bitrate: int | None) -> tuple[tuple[str, Any], ...]:
    """--interface, --channel, --bitrate and --data-bitrate as [can] settings (a data bitrate means CAN FD)."""
    given = {"interface": interface, "channel": channel, "bitrate": bitrate, "data_bitrate": data_bitrate,
             "fd": True if data_bitrate is not None else None}
    return tuple((k, v) for k, v in given.items() if v is not None)


CameraOpt = kind_option(CAMERAS, "--camera")
ArmOpt = kind_option(ARMS, "--arm")
SegmenterOpt = kind_option(SEGMENTERS, "--segmenter", " \\[default: gdino-sam2 where its weights are on this "
                           "machine, else rgbd]", optional=True)
EstimatorOpt = kind_option(ESTIMATORS, "--estimator", " \\[default: the config's, screw-grip]", optional=True)
MAX_CALIBRATION_ERROR = (100.0, 10.0)  # mm, deg: far past any calibration a run could act on


def _calibration_error(value: tuple[float, float]) -> tuple[float, float]:
    """Refuse a simulated calibration error outside 0..MAX_CALIBRATION_ERROR."""
    (mm, deg), (max_mm, max_deg) = value, MAX_CALIBRATION_ERROR
    if not (0.0 <= mm <= max_mm and 0.0 <= deg <= max_deg):
        raise typer.BadParameter(f"{mm:g} mm {deg:g} deg is outside 0-{max_mm:g} mm and 0-{max_deg:g} deg (a field "
                                 "hand-eye calibration is off by about 5 mm and 0.5 deg)")
    return value


CalibrationErrorOpt = Annotated[tuple[float, float], typer.Option(
    "--calibration-error", metavar="MM DEG", callback=_calibration_error,
    help="Simulation: the calibrated camera pose is off by MM (0-100) and DEG (0-10), each in a random direction "
    "drawn from the seed, as a field hand-eye calibration is; 0 0 for the exact pose.")]
ConfigFileOpt = Annotated[Path | None, typer.Option(
    "--config", metavar="FILE", help="The run's TOML config: \\[filter] (profile, radius_m, eps) \\[geometry] "
    "\\[estimator] \\[opening] (targets, steps, speeds, timeouts) \\[perception] (prompts, box, thresholds, models); "
    "options given here override it (see Configuration in docs/quickstart.md).")]
FilterOpt = Annotated[FilterChoice | None, typer.Option(
    "--filter", help="Cloud filter: sparse (the paper's real-camera setting: radius 1.3 cm, eps 1) or sim (its "
    "simulation setting: radius 0.05 m, eps 100) \\[default: the config's, else sim for simulated cameras and "
    "recordings made in simulation, sparse for real cameras and their recordings].")]
PromptOpt = Annotated[str | None, typer.Option(
    "--prompt", help="What to segment (the detector's text prompt) \\[default: the config's, cabinet].")]
BoxOpt = Annotated[tuple[float, float, float, float] | None, typer.Option(
    "--box", metavar="X0 Y0 X1 Y1", help="The object's box in the first frame (pixels); skips the detector "
    "(needed by --segmenter classical).")]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object instead of a table (on an error: "
                                       "{error, kind, exit_code, motors}).")]
PolicyOpt = Annotated[PolicyChoice, typer.Option(help=f"{POLICIES.help()}.")]
RobotOpt = robot_option("Robot config: a shipped one's name (panda_sim, openarm, damiao_6dof) or a TOML file "
                        "\\[default: panda_sim].")
StationSeedOpt = seed_option("Seed of the station generator (and sim noise).")
SimFaultOpt = sim_fault_option()
WORLD_HELP = "; ".join(f"{name}: {text}" for name, text in WORLDS.items())
WorldOpt = Annotated[WorldChoice, typer.Option("--world", help=f"The simulated world: {WORLD_HELP}.")]
PartOpt = Annotated[str | None, typer.Option(
    "--part", metavar="NAME|N|LINK", help="The part to open: its name ('top drawer', 'left door'), an index N (0 = "
    "the first of the task's kind, top to bottom then left to right as the camera sees them) or the model's link "
    "name; an unknown one lists the parts \\[default: the seed picks one within the robot's reach].")]
AssetsOpt = Annotated[Path | None, typer.Option(
    "--assets", metavar="DIR", help="A folder of PartNet-Mobility objects (<id>/mobility.urdf, semantics.txt, "
    "textured meshes): the target furniture is one of them, placed in a kitchen.")]
ObjectOpt = Annotated[str | None, typer.Option(
    "--object", metavar="ID", help="With --assets: the object to open \\[default: the usable objects cycled by "
    "seed].")]
ScaleOpt = Annotated[ScaleChoice, typer.Option(
    "--scale", help="With --assets, how objects are sized: " + "; ".join(f"{k}: {v}" for k, v in SCALES.items())
    + ".")]
PointOpt = Annotated[tuple[float, float] | None, typer.Option(
    "--point", metavar="U V", help="The pixel (column U, row V) on the part to open in the first frame, as a user "
    "points at it: on its front or on its handle \\[default: with --camera sim the simulated user's, said on the step "
    "log; on hardware none].")]
