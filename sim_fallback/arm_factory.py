"""Build any arm by name: "can" and "ideal" (drivers), "sim" (SimArm) and "sim-can" (CanArm on simulated motors).

sim-can runs the CanArm in lockstep with the simulated motors (one motor step per control cycle, on the caller's
clock): deterministic and unaffected by machine load. Without a world the motors are unloaded integrated joints;
with one they are the world's Panda (one physics step per cycle, faster than real time). `lockstep=False` gives
the motors their own thread and the CanArm its realtime loop, exactly as on hardware (benchmarks, loop tests).
"""

from __future__ import annotations

import itertools
from pathlib import Path

from drivers.arm.base import Arm
from drivers.arm.can_arm import CanArm
from drivers.arm.can_bus import CanBus
from drivers.arm.factory import DRIVER_ARMS
from drivers.arm.factory import open_arm as open_driver_arm
from drivers.arm.robot_config import RobotConfig
from drivers.errors import ArmError
from sim_fallback.arm import SimArm
from sim_fallback.can_motors import MotorFaults, PyBulletMotors, SimMotorBus
from sim_fallback.world import SimWorld

ARMS = (*DRIVER_ARMS, "sim", "sim-can")
PANDA_SIM_CONFIG = Path(__file__).resolve().parents[1] / "configs" / "robots" / "panda_sim.toml"  # the simulated Panda
_channels = itertools.count()


def open_arm(spec: str, config: RobotConfig, world: SimWorld | None = None) -> Arm:
    """An arm of kind `spec` ("can", "ideal", "sim", "sim-can"); "sim" needs `world`. SimArm is connected on
    construction; the others are connected by `with arm:` (or `connect()`)."""
    if spec in DRIVER_ARMS:
        return open_driver_arm(spec, config)
    if spec == "sim":
        if world is None:
            raise ArmError("arm 'sim' needs a simulated world: use it from `deploy open-*`, or use --arm sim-can")
        _check_panda(config, world)
        return SimArm(world, config.kinematics())
    if spec == "sim-can":
        return sim_can_arm(config, world)[0]
    raise ArmError(f"arm {spec!r} is not one of {', '.join(ARMS)}: pick one with --arm")


def sim_can_arm(config: RobotConfig, world: SimWorld | None = None, faults: dict[str, MotorFaults] | None = None,
                lockstep: bool = True) -> tuple[CanArm, SimMotorBus]:
    """A CanArm on simulated Damiao motors (on a private virtual channel), and the motors (for fault injection).

    `faults` maps joint names ("gripper") to faults present from the start. `lockstep` runs the motors on the
    arm's cycle; False: in their own thread on the wall clock, with the CanArm's realtime loop (no world)."""
    if world is not None and not lockstep:
        raise ArmError("a simulated world steps on the arm's cycle: sim-can with a world needs lockstep=True")
    if config.can.interface == "virtual":
        channel = f"{config.can.channel}-{next(_channels)}"
        config = config.model_copy(update={"can": config.can.model_copy(update={"channel": channel})})
    if world is None:
        motors = SimMotorBus(config)
    else:
        _check_panda(config, world)
        motors = SimMotorBus(config, PyBulletMotors(SimArm(world, config.kinematics()), config))
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


def _check_panda(config: RobotConfig, world: SimWorld) -> None:
    if tuple(config.joint_names) != tuple(world.robot_spec.arm_joints):
        raise ArmError(f"robot config {config.name!r} is not the simulated Panda (joints {config.joint_names}): "
                       "use configs/robots/panda_sim.toml with the simulation")
