"""One opening episode on any camera and arm, as explicit stages over one state record:

    perceive -> grasp -> [probe and classify] -> first pull -> axis-guided steps (re-grasp on a slip)

The controller sees only what a real robot senses: camera frames and the arm (measured joints, forward
kinematics). Progress is the grip point's travel along / about the estimated axis since the grasp. Frames are
grabbed during motions and processed between them (`Observer`). The stages are deploy/control/stages.py, what
they share `Episode` (deploy/control/context.py).
"""

from __future__ import annotations

import numpy as np

from deploy.config import Config
from deploy.control import stages
from deploy.control.context import Episode
from deploy.control.observer import Observer
from deploy.control.run_folder import RunFolder
from deploy.control.state import EpisodeResult, EpisodeState, EpisodeStop, StopReason
from deploy.control.viewer import RerunViewer
from deploy.errors import PerceptionError
from deploy.geometry.types import JointType
from deploy.perception.base import Segmenter
from deploy.perception.self_filter import SelfFilter
from drivers.arm.base import Arm
from drivers.arm.kinematics import Kinematics
from drivers.arm.motion import Compliance
from drivers.arm.robots import panda
from drivers.arm.trajectory import MotionLimits
from drivers.camera.base import Camera
from drivers.errors import ArmError, IKError
from drivers.interrupts import Interrupted, interrupts

TASK_JOINT = {"drawer": JointType.PRISMATIC, "door": JointType.REVOLUTE}


def run_episode(
    camera: Camera,
    arm: Arm,
    kin: Kinematics,
    segmenter: Segmenter,
    config: Config,
    folder: RunFolder | None = None,
    joint_limits: MotionLimits | None = None,
    viewer: RerunViewer | None = None,
    dry_run: bool = False,
    self_filter: SelfFilter | None = None,
    compliance: Compliance | None = None,
) -> EpisodeResult:
    """Open the object in view to `config.opening`'s target; always leaves the arm stopped.

    folder: the run folder (frames and motions are written as they come; the caller finishes it with
    `RunFolder.finish`). joint_limits: free-space joint moves (default 0.3 of the Panda's limits).
    dry_run: perceive and plan the grasp, command nothing. self_filter: removes the arm's own pixels.
    compliance: how pulls yield (the robot config's [compliance]; default `Compliance()`).
    """
    state = EpisodeState(t0=arm.time(), joint=TASK_JOINT.get(config.opening.task))
    observer = Observer(camera, segmenter, kin, config, state.joint, state.t0, folder, viewer, self_filter)
    episode = Episode(camera, arm, kin, segmenter, config,
                      joint_limits or MotionLimits.for_robot(panda(), kin, 0.3), observer, state, folder,
                      compliance or Compliance())
    interrupted = None
    try:
        with interrupts():  # Ctrl-C / SIGTERM end the episode here, so that its run folder can be finished
            reason, message = stages.run(episode, dry_run)
    except EpisodeStop as stop:
        reason, message = stop.reason, stop.message
    except IKError as exc:
        reason, message = StopReason.IK_INFEASIBLE, str(exc)
    except ArmError as exc:
        reason, message = StopReason.ARM_ERROR, str(exc)
    except PerceptionError as exc:  # the segmenter lost the object and could not find it again
        reason, message = StopReason.TRACKING_LOST, str(exc)
    except Interrupted as stop:
        reason, message, interrupted = StopReason.INTERRUPTED, stop.message, stop
    finally:
        arm.stop()
        if viewer is not None:
            viewer.close()
    result = _result(episode, reason, message)
    if interrupted is not None:  # the caller finishes the run folder with the result so far, then stops too
        interrupted.result = result
        raise interrupted
    return result


def _result(episode: Episode, reason: StopReason, message: str) -> EpisodeResult:
    state = episode.state
    state.timings["estimate_s"] += episode.observer.seconds
    state.timings["sim_time_s"] = episode.now()
    frame_ms = episode.observer.frame_ms
    if frame_ms:
        state.timings.update({"frame_ms_median": float(np.median(frame_ms)),
                              "frame_ms_p90": float(np.percentile(frame_ms, 90)),
                              "frame_cpu_ms_median": float(np.median(episode.observer.frame_cpu_ms))})
    return EpisodeResult(
        success=state.axis is not None and state.opened >= episode.target(), opened=state.opened,
        target=episode.target(), steps=state.steps, joint_type=state.joint_type().value, axis=state.axis,
        stop_reason=reason, message=message, run_dir=None if episode.folder is None else episode.folder.path,
        timings=state.timings, regrasped=state.regrasped, peak_pull_force_n=state.peak_pull_force_n,
        vision_axis=state.vision_axis, estimates=state.estimates,
        commanded=np.array(state.commanded).reshape(-1, 4, 4), measured=np.array(state.measured).reshape(-1, 4, 4),
        opening_curve=state.opening_curve, first_frame=episode.observer.first_frame,
    )
