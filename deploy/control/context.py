"""What every stage of an episode works with (`Episode`): the arm, the run's settings and policy, what the robot
config gives (free-space limits, grip force, compliance), the observer, the state record, and one pull with frames
grabbed on the way."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from deploy.config import Config
from deploy.control.observer import Observer
from deploy.control.state import EpisodeState, display_scale
from deploy.control.view import EpisodeView
from deploy.geometry.types import JointType
from deploy.perception.handle import GripperSize
from deploy.policies import OpeningPolicy
from deploy.report.run_folder import RunFolder
from drivers.arm.base import Arm, ArmState
from drivers.arm.kinematics import Kinematics
from drivers.arm.motion import Compliance, PathFn, PathResult, follow_cartesian_path
from drivers.arm.robot_config import RobotConfig
from drivers.arm.trajectory import MotionLimits

MIN_GRASP_WIDTH_M = 0.003  # a closed gripper narrower than this holds nothing
SETTLE_S = 0.3  # after a motion the arm settles on its last command (a new motion starts from the
# measured joints, and the safety layer refuses a jump from the last command to them)


ARM_VIEW_S = 0.1  # the viewer shows the arm's joints this often (arm time), besides with every frame
FREE_SPACE_SHARE = 0.3  # free-space joint moves at this share of the robot config's limits
OVERSHOOT = {JointType.PRISMATIC: 0.015, JointType.REVOLUTE: float(np.radians(5.0))}  # steps aim this far past
# the target, so that an opening measured a little long still leaves the object open to the target
GOAL_TOLERANCE = {JointType.PRISMATIC: 0.005, JointType.REVOLUTE: float(np.radians(1.0))}  # the goal is reached
# this close to it


@dataclass
class Episode:
    """What every stage works with: the arm, the run's settings and its policy, the robot config's free-space
    limits (`joint_limits`), grip force and compliance (how pulls yield), the observer (the only way to what the
    camera saw), the state record, what the episode reports to (`view`), the run folder and how wide the gripper
    opens (`gripper`, to judge a handle)."""

    arm: Arm
    config: Config
    policy: OpeningPolicy
    joint_limits: MotionLimits
    grip_force_n: float
    compliance: Compliance
    observer: Observer
    state: EpisodeState
    view: EpisodeView
    folder: RunFolder | None = None
    gripper: GripperSize = GripperSize()

    @classmethod
    def of_robot(cls, arm: Arm, config: Config, robot: RobotConfig, observer: Observer, state: EpisodeState,
                 view: EpisodeView, folder: RunFolder | None = None) -> Episode:
        """The episode of `arm` on `robot`'s config: its free-space limits, grip force and compliance."""
        gripper = GripperSize(robot.gripper.max_width_m if robot.gripper else 0.0)
        return cls(arm, config, config.opening.strategy(), robot.motion_limits(arm.kin, FREE_SPACE_SHARE),
                   robot.grip_force_n, robot.compliance.gains(), observer, state, view, folder, gripper)

    @property
    def kin(self) -> Kinematics:
        return self.arm.kin

    def tool(self) -> np.ndarray:
        """The measured tool pose (4x4, base frame)."""
        return self.kin.fk(self.arm.state().q)

    def now(self) -> float:
        """Arm-clock seconds since the episode started."""
        return self.arm.time() - self.state.t0

    def wait(self, duration_s: float) -> None:
        """Hold the last command for `duration_s` of arm time."""
        for _ in range(int(round(duration_s / self.arm.control_period_s))):
            self.arm.sync()

    def show_arm(self, state: ArmState, _t: float = 0.0) -> None:
        """The arm's state and command to the viewer, every ARM_VIEW_S of arm time: the `on_tick` of Cartesian
        motions, which read the state every tick anyway (a reading more would change a simulated arm's sensor
        noise, and so the run)."""
        if self.view.showing:
            self.view.arm(state.t - self.state.t0, state, self.arm.commanded_q(), ARM_VIEW_S)

    def line_limits(self) -> MotionLimits:
        v = self.config.opening.pull_speed_m_s
        return MotionLimits(v, 4 * v, 40 * v)

    def arc_limits(self) -> MotionLimits:
        v = float(np.radians(self.config.opening.pull_speed_deg_s))
        return MotionLimits(v, 4 * v, 40 * v)

    def target(self) -> float:
        """The target opening of the joint acted on (m or rad)."""
        return self.config.opening.target_for(self.state.joint_type())

    def goal(self, joint: JointType) -> float:
        """Where the steps aim: the target plus the overshoot (m or rad)."""
        return self.target() + OVERSHOOT[joint]

    def shown(self, value: float) -> float:
        """An opening in the units users read: m for a drawer, deg for a door."""
        return value * display_scale(self.state.joint_type())

    def gripping(self) -> bool:
        return holds(self.arm.state())

    def pull(self, path: PathFn, length: float, label: str, limits: MotionLimits | None = None,
             step: bool = False) -> PathResult:
        """One compliant motion along `path` with frames grabbed on the way (an axis-guided `step` is counted
        once it has moved), then the frames processed. The path yields to the object and the force is bounded
        by `[opening] pull_force_limit_n` (`Compliance`); the caller decides what a slip or a block means. The
        motion stops early when the gripper loses the handle or the episode's arm time (`timeout_s`) runs out."""
        clock, start_s = time.perf_counter(), self.now()

        def on_tick(state: ArmState, _t: float) -> bool:
            held = holds(state)  # a slip ends the pull; its frames are not held
            self.observer.capture(state, held, self.arm.commanded_q)
            self.show_arm(state)
            return held and self.now() <= self.config.opening.timeout_s

        self.arm.set_compliance(True)
        try:
            compliance = self.compliance.with_force_limit(self.config.opening.pull_force_limit_n)
            result = follow_cartesian_path(self.arm, self.kin, path, max(length, 1e-4),
                                           limits or self.line_limits(), on_tick, compliance=compliance)
            self.wait(SETTLE_S)
        finally:
            self.arm.set_compliance(False)
        settled = self.arm.state()
        self.observer.settled(settled, holds(settled), self.arm.commanded_q)
        self.state.timings["motion_s"] += time.perf_counter() - clock
        self.state.steps += step
        self.state.peak_pull_force_n = max(self.state.peak_pull_force_n, result.peak_force_n)
        self.state.across_force_n = result.across_force_n
        self.state.commanded.extend(result.planned)
        self.state.measured.extend(result.measured)
        if self.folder is not None:
            self.folder.add_motion(label, result, start_s)
        self.view.motion(self.now(), label, result.planned, result.measured)
        self.observer.process()
        return result


def holds(state: ArmState) -> bool:
    """Whether the gripper holds something at `state`: its fingers stopped short of closing."""
    return state.gripper_width_m > MIN_GRASP_WIDTH_M
