"""The camera and arm `deploy calibrate` runs on, chosen by --camera, --arm and --robot.

Any live kind of the registries: a simulated camera with a simulated arm (`--camera sim` with `--arm sim`, the
world's Panda, or `--arm sim-can`, the real CAN driver on simulated Damiao motors that move the same Panda) in the
simulated calibration scene of deploy.rig, with its ground truth; a physical camera with a physical arm
(`--camera d415[:SERIAL]` with `--arm can --robot CONFIG.toml`). The pairing rules are the rig's
(`deploy.rig.check_spec`). A recording (`replay:PATH`) is refused: calibration moves the arm, and a recording
cannot show those motions; so is an arm that moves nothing a camera sees (`ideal`).

Opening order: specs and the robot config are checked first, then the camera is connected (its serial names the
calibration file), then the arm is probed (joints read, nothing enabled) so the stations can be planned and shown.
`Devices.start` asks before a real arm's first motion and only then enables it; leaving `open_devices` always
stops the arm (damp, disable) and releases the camera; an exception leaving it carries the motors' final states.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calibration.board import BoardConfig
from calibration.detect import BoardDetector
from calibration.routine import RoutineConfig, plan_around_start
from calibration.store import HandEyeRecord
from deploy.arm_bringup import released
from deploy.errors import ConfigError
from deploy.rig import BoardScene, RigSpec, check_spec, load_robot, open_rig
from drivers.arm.base import Arm
from drivers.arm.kinematics import Kinematics
from drivers.arm.registry import ARMS
from drivers.arm.robot_config import PANDA_SIM_CONFIG, RobotConfig, load_robot_config
from drivers.arm.trajectory import MotionLimits, joint_trajectory
from drivers.camera.base import Camera
from drivers.camera.registry import CAMERAS
from drivers.errors import ArmError
from drivers.registry import Entry, Registry

SPEED_FRACTION = 0.5  # stations are visited at this share of the velocity, acceleration and jerk limits
MAX_DRIFT_RAD = 0.02  # the arm may not move more than this between planning and enabling
NO_PIVOT = ("--pivot-mm X Y Z is needed on a real arm: the board centre in the tool frame (eye-to-hand, e.g. 0 0 30 "
            "for a board 3 cm beyond the tool point) or the point the wrist camera looks at (eye-in-hand, e.g. "
            "0 0 450); the stations turn about it so the board stays in view")


@dataclass(frozen=True)
class DeviceChoice:
    """--camera, --arm and the robot config, checked against each other."""

    camera: str
    arm: str
    robot: RobotConfig
    pivot_mm: tuple[float, float, float] | None = None
    robot_path: Path | None = None
    can: tuple = ()  # the command line's [can] settings over the robot config's

    @property
    def simulated(self) -> bool:
        return CAMERAS.entry(self.camera)[0].simulated

    @property
    def real_arm(self) -> bool:
        return ARMS.entry(self.arm)[0].hardware


def choose(camera: str, arm: str | None, robot: Path | None, pivot_mm: tuple[float, float, float] | None = None,
           pivot_from_record: bool = False, can: tuple = ()) -> DeviceChoice:
    """Check the camera and arm specs (live kinds, paired by the rig's rules), the pivot (needed on a real arm
    unless a stored calibration gives it) and load the robot config (default arm: the first live arm as simulated
    as the camera, `sim` with the sim camera and `can` with a D415; default robot for simulated arms: the shipped
    panda_sim). ConfigError naming the fix otherwise."""
    camera_entry = _live_entry(CAMERAS, camera, "--camera", "needs live images of each pose, which a recording "
                                                             "cannot show")
    arm = arm or next(e.name for e in live(ARMS) if e.simulated == camera_entry.simulated)
    arm_entry = _live_entry(ARMS, arm, "--arm", "needs an arm that moves what the camera sees")
    check_spec(RigSpec(camera=camera, arm=arm, robot=robot))
    if arm_entry.hardware and pivot_mm is None and not pivot_from_record:
        raise ConfigError(NO_PIVOT)
    config = load_robot(arm, robot, can)
    if arm_entry.simulated and config.joint_names != load_robot_config(PANDA_SIM_CONFIG).joint_names:
        raise ConfigError(f"{config.label} is not the simulated Panda: use --robot panda_sim (or none) "
                          "with the simulation")
    return DeviceChoice(camera, arm, config, pivot_mm, robot, can)


def live(registry: Registry) -> list[Entry]:
    """The kinds calibration can use (simulated ones first, then physical ones): not recordings, not stand-ins."""
    return sorted((e for e in registry.entries() if e.live), key=lambda e: not e.simulated)


def _live_entry(registry: Registry, spec: str, flag: str, why: str) -> Entry:
    """The registry entry of `spec`, its argument checked; ConfigError when it is not a live kind (`why` says
    what calibration needs that a registered but not live kind lacks)."""
    entry = {e.name: e for e in registry.entries()}.get(spec.partition(":")[0])
    if entry is None or not entry.live:
        reason = f": calibration moves the arm and {why}" if entry is not None else ""
        raise ConfigError(f"{flag} {spec!r} is not one of {', '.join(e.usage for e in live(registry))}{reason}")
    return registry.entry(spec)[0]


@dataclass(frozen=True)
class StationPlan:
    """The stations the arm will visit (joints), with their tool poses, from the start joints."""

    q_start: np.ndarray
    stations: list[np.ndarray]
    tools: list[np.ndarray]
    T_start: np.ndarray
    duration_s: float

    @property
    def max_shift_m(self) -> float:
        return max(float(np.linalg.norm(T[:3, 3] - self.T_start[:3, 3])) for T in self.tools)

    @property
    def max_turn_deg(self) -> float:
        return max(_angle_deg(self.T_start[:3, :3].T @ T[:3, :3]) for T in self.tools)

    def to_dict(self) -> dict:
        return {
            "q_start": self.q_start.round(4).tolist(), "tool_start_m": self.T_start[:3, 3].round(4).tolist(),
            "duration_s": round(self.duration_s, 1), "max_shift_m": round(self.max_shift_m, 4),
            "max_turn_deg": round(self.max_turn_deg, 2),
            "stations": [{"q": q.round(4).tolist(), "tool_position_m": T[:3, 3].round(4).tolist(),
                          "turn_deg": round(_angle_deg(self.T_start[:3, :3].T @ T[:3, :3]), 2)}
                         for q, T in zip(self.stations, self.tools, strict=True)],
        }


@dataclass
class Devices:
    """An open camera and a probed arm (not yet enabled: call `start`). `rig` (with the ground truth) and `motors`
    (sim-can's simulated motors) are set in simulation only."""

    choice: DeviceChoice
    camera: Camera
    arm: Arm
    kin: Kinematics
    serial: str
    limits: MotionLimits
    rig: object | None = None
    motors: object | None = None

    @property
    def robot_id(self) -> str:
        return self.choice.robot.name

    @property
    def real_arm(self) -> bool:
        return self.choice.real_arm

    def pivot(self, record: HandEyeRecord | None = None) -> tuple[float, float, float]:
        """The stations' pivot in the tool frame (m): --pivot-mm, else the sim rig's, else (check) the board centre
        or look point the stored calibration gives; ConfigError when none is known."""
        if self.choice.pivot_mm is not None:
            return tuple(float(v) / 1000 for v in self.choice.pivot_mm)  # type: ignore[return-value]
        if self.rig is not None:
            return self.rig.pivot_tool_m
        if record is not None:
            return pivot_from_record(record, self.kin.fk(self.arm.state().q))
        raise ConfigError(NO_PIVOT)

    def plan(self, cfg: RoutineConfig) -> StationPlan:
        """The stations the routine will visit from the arm's current joints (checked by IK, limits, workspace)."""
        q0 = self.arm.state().q
        stations = plan_around_start(self.kin, self.arm, cfg)
        settle = cfg.settle_s * len(stations)
        path = [q0, *stations, q0]
        moves = zip(path[:-1], path[1:], strict=True)
        duration = sum(joint_trajectory(a, b, self.limits).duration for a, b in moves) + settle
        return StationPlan(q0, stations, [self.kin.fk(q) for q in stations], self.kin.fk(q0), duration)

    def board_visible(self, board: BoardConfig, record: HandEyeRecord | None = None) -> bool:
        """Whether one image shows the board (commands nothing)."""
        intrinsics = record.intrinsics if record is not None else self.camera.intrinsics
        distortion = record.distortion if record is not None else None
        return BoardDetector(board).pose(self.camera.read().color, intrinsics, distortion) is not None

    def start(self, plan: StationPlan, confirm: Callable[[str], None] | None) -> None:
        """Ask `confirm` (real arm only; it aborts by raising), enable the arm, check it has not moved since the
        plan was made."""
        if self.real_arm and confirm is not None:
            confirm(f"The arm {self.robot_id!r} will visit {len(plan.stations)} stations around its current pose "
                    f"(tool within {plan.max_shift_m * 100:.0f} cm and {plan.max_turn_deg:.0f} deg of it, about "
                    f"{plan.duration_s:.0f} s, {SPEED_FRACTION:.0%} speed, no collision checking). "
                    "Area clear, arm supervised, e-stop at hand?")
        self.arm.connect()
        drift = float(np.abs(self.arm.state().q - plan.q_start).max())
        if drift > MAX_DRIFT_RAD:
            self.arm.stop()
            raise ArmError(f"the arm moved {drift:.3f} rad between planning and enabling: hold it still and run the "
                           "command again")


def pivot_from_record(record: HandEyeRecord, T_base_tool: np.ndarray) -> tuple[float, float, float]:
    """The board centre in the tool frame: eye-to-hand from the stored board mount; eye-in-hand from the stored
    board pose and the current tool pose (the point the wrist camera looks at)."""
    centre = np.append(record.board.center_m, 1.0)
    T_tool_board = record.T_board if record.setup == "eye-to-hand" else np.linalg.inv(T_base_tool) @ record.T_board
    return tuple(float(v) for v in (T_tool_board @ centre)[:3])  # type: ignore[return-value]


@contextmanager
def open_devices(choice: DeviceChoice, setup: str = "eye-to-hand", board: BoardConfig | None = None,
                 seed: int = 0) -> Iterator[Devices]:
    """Connect the camera, then probe the arm (nothing enabled); on leaving, stop the arm and release both.
    In simulation `setup` and `board` build the calibration scene (board on the tool or on the table)."""
    scene = BoardScene(setup, board or BoardConfig(), seed)  # type: ignore[arg-type]
    with open_rig(RigSpec(camera=choice.camera, arm=choice.arm, robot=choice.robot_path, can=choice.can,
                          scene=scene)) as rig, \
            released(rig.arm):
        rig.arm.probe()
        motors = None
        if choice.simulated and rig.arm.bus_channel is not None:
            from sim_fallback.can_motors import motors_on

            motors = motors_on(rig.arm.bus_channel)
        limits = choice.robot.motion_limits(rig.kin, SPEED_FRACTION)
        yield Devices(choice, rig.camera, rig.arm, rig.kin, rig.serial, limits, rig.board, motors)


def _angle_deg(R: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1.0, 1.0))))
