"""One opening episode on any camera and arm, as explicit stages over one state record:

    perceive -> grasp -> [probe and classify] -> first pull -> axis-guided steps (re-grasp on a slip)

The controller sees only what a real robot senses: camera frames and the arm (measured joints, forward
kinematics). Progress is the grip point's travel along / about the estimated axis since the grasp. Frames are
grabbed during motions and processed between them (`Observer`). The stages are deploy/control/stages.py (the hand
on the handle: hand.py; pulls past the arm's reach: out_of_reach.py), what they share `Episode`
(deploy/control/context.py).
"""

from __future__ import annotations

import numpy as np

from deploy.config import Config
from deploy.control import stages
from deploy.control.context import Episode
from deploy.control.observer import Observer
from deploy.control.state import EpisodeResult, EpisodeState, EpisodeStop, StopReason
from deploy.control.view import EpisodeView
from deploy.errors import PerceptionError
from deploy.geometry.types import JointType
from deploy.perception.base import Segmenter
from deploy.perception.self_filter import SelfFilter
from deploy.report.run_folder import RunFolder
from drivers.arm.base import Arm
from drivers.arm.robot_config import RobotConfig
from drivers.camera.base import Camera
from drivers.errors import ArmError, IKError
from drivers.interrupts import Interrupted, interrupts

TASK_JOINT = {"drawer": JointType.PRISMATIC, "door": JointType.REVOLUTE}


def run_episode(
    camera: Camera,
    arm: Arm,
    segmenter: Segmenter,
    config: Config,
    robot: RobotConfig,
    folder: RunFolder | None = None,
    view: EpisodeView | None = None,
    dry_run: bool = False,
    self_filter: SelfFilter | None = None,
) -> EpisodeResult:
    """Open the object in view to `config.opening`'s target with `config.opening.policy`; always leaves the arm
    stopped.

    robot: the arm's robot config (free-space limits, grip force, compliance). folder: the run folder (frames and
    motions are written as they come; the caller finishes it with `RunFolder.finish`). view: step lines and the
    rerun viewer (default: step lines only). dry_run: perceive and plan the grasp, command nothing. self_filter:
    removes the arm's own pixels.
    """
    state = EpisodeState(t0=arm.time(), joint=TASK_JOINT.get(config.opening.task))
    view = view or EpisodeView()
    observer = Observer(camera, segmenter, arm.kin, config, state.joint, state.t0, folder, view, self_filter)
    episode = Episode.of_robot(arm, config, robot, observer, state, view, folder)
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
        view.close()
    result = _result(episode, reason, message)
    if interrupted is not None:  # the caller finishes the run folder with the result so far, then stops too
        interrupted.result = result
        raise interrupted
    return result


def _result(episode: Episode, reason: StopReason, message: str) -> EpisodeResult:
    state, times = episode.state, episode.observer.times()
    state.timings["estimate_s"] += times.seconds
    state.timings["sim_time_s"] = episode.now()
    if times.frame_ms:
        state.timings.update({"frame_ms_median": float(np.median(times.frame_ms)),
                              "frame_ms_p90": float(np.percentile(times.frame_ms, 90)),
                              "frame_cpu_ms_median": float(np.median(times.frame_cpu_ms))})
    return EpisodeResult(
        success=state.axis is not None and state.opened >= episode.target(), opened=state.opened,
        target=episode.target(), steps=state.steps, joint_type=state.joint_type().value, axis=state.axis,
        stop_reason=reason, message=message, run_dir=None if episode.folder is None else episode.folder.path,
        timings=state.timings, regrasped=state.regrasped, peak_pull_force_n=state.peak_pull_force_n,
        vision_axis=state.vision_axis, estimates=state.estimates,
        commanded=np.array(state.commanded).reshape(-1, 4, 4), measured=np.array(state.measured).reshape(-1, 4, 4),
        opening_curve=state.opening_curve,
        first_frame=None if episode.observer.first_look is None else episode.observer.first_look.frame,
    )
