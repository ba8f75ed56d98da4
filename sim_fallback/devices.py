"""The simulated devices behind the camera and arm registries (registered by sim_fallback/plugin.py).

- camera `sim`: a D415 rendered in the PyBullet world of the rig;
- arm `sim`: the world's arm (`SimArm`: the robot config's, the Panda by default), its joint torques measured as its
  Damiao motors would
  (sim_fallback/torque_sensing.py) and its finger pads' friction drawn per episode (`episode_signals`);
- arm `sim-can`: the real CAN driver (`CanArm`) talking to simulated Damiao motors on a virtual bus (its bare bus,
  for bring-up commands that address the motors directly, from `open_sim_can_bus`). In lockstep
  (default) the motors step with the CanArm's cycles on the caller's clock: deterministic and unaffected by
  machine load. Without a world the motors are unloaded integrated joints; with one they are the world's Panda
  (one physics step per cycle, the arm `sim`'s torque sensing and pads). `lockstep=False` gives the motors their
  own thread and the CanArm its realtime loop, exactly as on hardware (benchmarks, loop tests).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from drivers.arm.can_arm import CanArm
from drivers.arm.can_bus import CanBus
from drivers.arm.robot_config import RobotConfig
from drivers.camera.base import Intrinsics
from drivers.camera.depth_noise import DepthNoise
from drivers.errors import ArmError, CameraError
from sim_fallback.arm import SimArm
from sim_fallback.camera import SimCamera, d415_intrinsics
from sim_fallback.can_motors import MotorFaults, PyBulletMotors, SimMotorBus
from sim_fallback.torque_sensing import TorqueSensing
from sim_fallback.world import SimWorld

PAD_FRICTION_RANGE = (0.4, 0.8)  # rubber pads on lacquered or metal handles
SIGNALS_STREAM = 34  # the episode's random stream for its arm signals (its camera and calibration use others)

_channels = itertools.count()


@dataclass(frozen=True)
class EpisodeSignals:
    """What one episode's simulated arm senses and grips with: its torque sensing (None: PyBullet's exact torques)
    and its pads' friction."""

    torque_sensing: TorqueSensing | None
    pad_friction: float


def episode_signals(robot: RobotConfig, seed: int) -> EpisodeSignals:
    """The arm signals of episode `seed`: torque errors for `robot`'s motors and a pad friction in
    PAD_FRICTION_RANGE, both drawn from the seed."""
    rng = np.random.default_rng([seed, SIGNALS_STREAM])
    pad_friction = float(rng.uniform(*PAD_FRICTION_RANGE))
    return EpisodeSignals(TorqueSensing.for_robot(robot, rng.integers(2**63)), pad_friction)


def sensor_models(camera: SimCamera, robot: RobotConfig, seed: int) -> dict:
    """The sensor models in force in episode `seed` (for run folders and benchmark JSON): the camera's depth model,
    the arm's torque sensing, the pads' friction range and the friction drawn."""
    signals = episode_signals(robot, seed)
    torques = "exact (PyBullet's applied torques)" if signals.torque_sensing is None else \
        "motor current as Damiao motors measure it: 12 bits over +-TMAX, offset, drifting bias, noise"
    return {"depth": camera.depth_model, "torque_sensing": torques, "pad_friction_range": list(PAD_FRICTION_RANGE),
            "pad_friction": round(signals.pad_friction, 4)}


def open_sim_camera(_argument: str, world: SimWorld | None = None, width: int = 640, height: int = 480,
                    fps: float = 10.0, seed: int = 0, noise: DepthNoise | None = None,
                    intrinsics: Intrinsics | None = None, labels: bool = False) -> SimCamera:
    """The simulated D415 of `world` at width x height (D415 field of view), `fps` on the simulated clock (at most
    the physics rate: CameraError above it); its frames carry no pose (the rig adds the calibrated one) and labels
    only when asked (the oracle ablation)."""
    if world is None:
        raise CameraError("camera 'sim' needs a simulated world: use it from a rig (`deploy open-* --camera sim`)")
    rate = 1.0 / world.clock.dt  # a frame per physics step at most: faster slots would repeat a step's image
    if fps > rate + 1e-9:
        raise CameraError(f"camera sim: --fps {fps:g} is more than the simulated camera gives: at most {rate:g} "
                          f"frames per second (its physics rate); pass --fps {rate:g} or less")
    return SimCamera(world, intrinsics=intrinsics or d415_intrinsics(width, height), noise=noise, seed=seed, fps=fps,
                     labels=labels)


def open_sim_arm(_argument: str, robot: RobotConfig, world: SimWorld | None = None) -> SimArm:
    """The world's arm, connected on construction, with the signals of the world's episode."""
    if world is None:
        raise ArmError("arm 'sim' needs a simulated world: use it with --camera sim, or use --arm sim-can")
    _check_robot(robot, world)
    return _episode_arm(robot, world)


def open_sim_can_arm(_argument: str, robot: RobotConfig, world: SimWorld | None = None) -> CanArm:
    """A CanArm on simulated Damiao motors, in lockstep (the world's arm when `world` is given)."""
    return sim_can_arm(robot, world)[0]


def open_sim_can_bus(robot: RobotConfig) -> tuple[CanBus, SimMotorBus]:
    """The bus of a sim-can arm with no arm on top, and the simulated motors answering on it (unloaded joints,
    in lockstep: they answer as the bus is read); close both after."""
    arm, motors = sim_can_arm(robot)
    return arm.bus, motors


def sim_can_arm(config: RobotConfig, world: SimWorld | None = None, faults: dict[str, MotorFaults] | None = None,
                lockstep: bool = True, signals: EpisodeSignals | None = None) -> tuple[CanArm, SimMotorBus]:
    """A CanArm on simulated Damiao motors (on a private channel of python-can's virtual interface, whatever
    interface the robot config names), and the motors (for fault injection).

    `faults` maps joint names ("gripper") to faults present from the start. `lockstep` runs the motors on the
    arm's cycle; False: in their own thread on the wall clock, with the CanArm's realtime loop (no world).
    `signals`: the world's arm's (None: its episode's, `episode_signals`)."""
    if world is not None and not lockstep:
        raise ArmError("a simulated world steps on the arm's cycle: sim-can with a world needs lockstep=True")
    # always python-can's in-process bus, on a channel of its own, whatever the config names (can0 on socketcan)
    channel = f"sim-{config.can.channel}-{next(_channels)}"
    can = config.can.model_copy(update={"interface": "virtual", "channel": channel})
    config = config.model_copy(update={"can": can})
    if world is None:
        motors = SimMotorBus(config)
    else:
        _check_robot(config, world)
        motors = SimMotorBus(config, PyBulletMotors(_episode_arm(config, world, signals), config))
    for name, f in (faults or {}).items():
        motors.motor(name).faults = f
    c = config.can
    if not lockstep:
        motors.start()
        bus = CanBus.from_config(c)
        return CanArm(config, bus, on_close=motors.close), motors
    bus = CanBus.from_config(c, pump=motors.poll)
    arm = CanArm(config, bus, realtime=False, on_cycle=lambda: motors.step(config.control_period_s),
                 on_close=motors.close)
    return arm, motors


def _episode_arm(robot: RobotConfig, world: SimWorld, signals: EpisodeSignals | None = None) -> SimArm:
    signals = signals or episode_signals(robot, world.scenario.seed)
    kin = robot.kinematics()
    return SimArm(world, kin, robot.safety_guard(kin), pad_friction=signals.pad_friction,
                  torque_sensing=signals.torque_sensing)


def _check_robot(config: RobotConfig, world: SimWorld) -> None:
    if tuple(config.joint_names) != tuple(world.robot_spec.arm_joints):
        raise ArmError(f"{config.label} is not the arm of the simulated world (joints {config.joint_names}, the "
                       f"world's {list(world.robot_spec.arm_joints)}): build the world with the config's "
                       "robot_spec()")
