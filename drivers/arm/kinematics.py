"""Forward and inverse kinematics of the arm's tool frame with Pinocchio (URDF, no meshes)."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pinocchio as pin

from drivers.arm.grasping import GRASP_DEPTH_M, LIMIT_MARGIN_RAD, UP, approach_poses, grasp_pose
from drivers.arm.robots import RobotSpec, panda
from drivers.errors import ArmError, IKError, JointSpeedError

IK_STEP_LIMIT = 1.0  # rad: largest joint change per iteration, keeps early steps from overshooting
IK_DAMPING = 1e-6  # damped least squares J^T (J J^T + lambda I)^-1: lambda away from singularities ...
IK_SINGULAR_VALUE, IK_SINGULAR_DAMPING = 0.05, 1e-4  # ... growing to this as J's smallest singular value -> 0
IK_POSTURE_GAIN = 0.05  # ik(): share of the way to the rest posture per iteration, in the null space, ...
IK_POSTURE_UNTIL = 10.0  # ... while the pose error is above this many tolerances (then converge fast)
LIMIT_BAND_RAD, LIMIT_WEIGHT = 1.0, 20.0  # track(): joints this near a limit also head to mid-range, weighted
TRACK_POSTURE_SHARE = 0.5  # track(): the posture step saturates at this share of a joint's step limit
IK_STALL_WINDOW, IK_STALL_RATIO = 20, 0.9  # give up when 20 iterations shrink the error < 10 %
PATH_MAX_JOINT_STEP_RAD = 0.5  # a larger jump between path waypoints means IK switched branch
GENERIC_SEEDS = 8  # well_conditioned_start on an arm of another layout: seeds drawn around its start ...
GENERIC_SPREAD_RAD = 0.4  # ... this far (std per joint)
SIDEWAYS_TURN_RAD, SIDEWAYS_LEAN_RAD, SIDEWAYS_TWIST_RAD = 1.2, 1.0, 2.0  # the elbow swung out to a side: joint 1
# turned off the target, joint 2 leaning that way, joint 3 turned back (`_sideways_seeds`), ...
SIDEWAYS_WRIST_RAD = ((1.8, 2.6), (-1.8, 2.6))  # ... the wrist's joints 5 and 6 as the template's or these


class Kinematics:
    """Kinematics of one serial arm reduced to its actuated joints, for one named tool frame.

    All poses are 4x4 homogeneous transforms of the tool frame in the robot base frame (metres).
    """

    def __init__(self, model: pin.Model, tool_frame: str) -> None:
        if not model.existFrame(tool_frame):
            names = ", ".join(f.name for f in model.frames)
            raise ArmError(f"tool frame {tool_frame!r} is not in the robot model; frames are: {names}")
        if model.nq != model.nv:
            raise ArmError(
                "robot model has continuous joints (nq != nv), which Kinematics does not support: "
                "give them position limits in the URDF"
            )
        self.model = model
        self.data = model.createData()
        self.tool_frame = tool_frame
        self._frame_id = model.getFrameId(tool_frame)

    @classmethod
    def from_urdf(cls, path: str | Path, tool_frame: str, locked_joints: Sequence[str] = ()) -> Kinematics:
        """Build from a URDF, locking `locked_joints` (e.g. fingers) at their zero position."""
        path = Path(path)
        full = _urdf_model(path)
        missing = [name for name in locked_joints if not full.existJointName(name)]
        if missing:
            raise ArmError(f"joints to lock {missing} are not in {path.name}: check the joint names")
        ids = [full.getJointId(name) for name in locked_joints]
        model = pin.buildReducedModel(full, ids, pin.neutral(full)) if ids else full
        return cls(model, tool_frame)

    @classmethod
    def from_robot(cls, robot: RobotSpec) -> Kinematics:
        return cls.from_urdf(robot.urdf, robot.tool_frame, robot.finger_joints)

    @classmethod
    def panda(cls) -> Kinematics:
        return cls.from_robot(panda())

    @property
    def dof(self) -> int:
        return self.model.nv

    @property
    def joint_names(self) -> list[str]:
        return list(self.model.names[1:])

    @property
    def q_min(self) -> np.ndarray:
        return self.model.lowerPositionLimit.copy()

    @property
    def q_max(self) -> np.ndarray:
        return self.model.upperPositionLimit.copy()

    @property
    def v_max(self) -> np.ndarray:
        return self.model.velocityLimit.copy()

    def _placement(self, q: np.ndarray) -> pin.SE3:
        pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[self._frame_id]

    def fk(self, q: np.ndarray) -> np.ndarray:
        """Tool pose (4x4) at joint positions q."""
        return self._placement(np.asarray(q, float)).homogeneous.copy()

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Tool Jacobian (6 x dof), [linear; angular], at the tool origin in base-aligned axes."""
        return pin.computeFrameJacobian(
            self.model, self.data, np.asarray(q, float), self._frame_id, pin.LOCAL_WORLD_ALIGNED
        )

    def ik(
        self,
        T_target: np.ndarray,
        q_seed: np.ndarray,
        tol_pos: float = 1e-4,
        tol_rot: float = 1e-3,
        max_iter: int = 200,
        restarts: int = 8,
        rng: np.random.Generator | None = None,
        q_rest: np.ndarray | None = None,
    ) -> np.ndarray:
        """Joint positions reaching tool pose `T_target` (tolerances in m and rad), nearest `q_seed` first.

        Damped least squares on log6(oMcurrent^-1 * oMdesired), clamped to the joint limits, with damping
        that grows near singularities and, in the null space of the pose, a pull of the arm's redundancy
        toward `q_rest` (default: the seed). When the seed does not converge, up to `restarts` random
        seeds within the limits are tried without that pull (from `rng`, default a fixed seed, so equal
        inputs give equal answers). Raises IKError when none converges.
        """
        oMdes = self._target(T_target)
        q = np.clip(np.asarray(q_seed, float), self.q_min, self.q_max)
        q_rest = q.copy() if q_rest is None else np.asarray(q_rest, float)
        rng = np.random.default_rng(0) if rng is None else rng
        best_pos_err, best_rot_err = np.inf, np.inf
        for attempt in range(restarts + 1):
            gain = IK_POSTURE_GAIN
            if attempt > 0:
                q, gain = rng.uniform(self.q_min, self.q_max), 0.0
            q, pos_err, rot_err = self._solve(oMdes, q, tol_pos, tol_rot, max_iter, q_rest, gain)
            if pos_err <= tol_pos and rot_err <= tol_rot:
                return q
            if pos_err < best_pos_err:
                best_pos_err, best_rot_err = pos_err, rot_err
        p = oMdes.translation
        raise IKError(
            f"target pose unreachable: tool at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m in the base frame "
            f"(position error {best_pos_err * 1e3:.1f} mm, rotation error {np.degrees(best_rot_err):.1f} deg "
            f"after {restarts + 1} attempts); move the object closer or change the grasp orientation"
        )

    def track(
        self,
        T_target: np.ndarray,
        q_prev: np.ndarray,
        max_step: np.ndarray,
        q_rest: np.ndarray,
        posture_gain: float,
        posture_scale: float = 1.0,
        tol_pos: float = 1e-6,
        tol_rot: float = 1e-5,
        max_iter: int = 20,
    ) -> np.ndarray:
        """One control tick of Cartesian tracking: joints reaching `T_target` (tolerances in m and rad)
        with no joint moving more than `max_step` (rad, per joint) from `q_prev`.

        First a step in the null space of the pose toward `q_rest` and, with a weight growing to
        LIMIT_WEIGHT, toward mid-range for joints within LIMIT_BAND_RAD of a limit: `posture_gain` of the
        way, saturating smoothly at TRACK_POSTURE_SHARE of max_step, times `posture_scale` (e.g. the path
        speed relative to its limit, so that this step starts and stops with the motion). This keeps the
        redundancy from drifting tick after tick. Then damped least squares within the limits and the step
        box. Raises IKError starting with "ik:" when the pose is not reached, or only with a joint moving
        onto a position limit or at its step limit (JointSpeedError: a slower path may pass).
        """
        oMdes = self._target(T_target)
        q_prev = np.asarray(q_prev, float)
        q_min, q_max = self.model.lowerPositionLimit, self.model.upperPositionLimit
        lower, upper = np.maximum(q_min, q_prev - max_step), np.minimum(q_max, q_prev + max_step)
        margin = np.minimum(q_prev - q_min, q_max - q_prev)
        weight = LIMIT_WEIGHT * np.clip(1.0 - margin / LIMIT_BAND_RAD, 0.0, 1.0) ** 2
        posture = (q_rest - q_prev) + weight * ((q_min + q_max) / 2 - q_prev)
        J = pin.computeFrameJacobian(self.model, self.data, q_prev, self._frame_id, pin.LOCAL)
        step = _dls_step(J, None, posture_gain * posture)
        ratio = float(np.max(np.abs(step) / (TRACK_POSTURE_SHARE * max_step)))
        step *= np.tanh(ratio) / ratio if ratio > 1e-9 else 1.0  # smooth saturation at the share
        q = np.clip(q_prev + posture_scale * step, lower, upper)
        q, pos_err, rot_err = self._solve(oMdes, q, tol_pos, tol_rot, max_iter, q_rest, 0.0, lower, upper)
        at_limit = ((q <= q_min) & (q < q_prev)) | ((q >= q_max) & (q > q_prev))
        at_step = np.abs(q - q_prev) >= max_step * (1.0 - 1e-9)
        if at_limit.any() or at_step.any():
            j = int(np.argmax(at_limit | at_step))
            bound = "position" if at_limit[j] else "velocity"
            why = f"needs joint {self.joint_names[j]} at its {bound} limit"
        elif pos_err > tol_pos or rot_err > tol_rot:
            why = (f"is not reached (position error {pos_err * 1e3:.4f} mm, rotation error "
                   f"{np.degrees(rot_err):.4f} deg left)")
        else:
            return q
        error = JointSpeedError if (at_step.any() and not at_limit.any()) else IKError
        raise error(
            f"ik: the tool pose {why}: the path passes near a singularity or a joint limit; slow the motion "
            "down, start from another arm configuration or shorten the path"
        )

    def _target(self, T_target: np.ndarray) -> pin.SE3:
        T_target = np.asarray(T_target, float)
        if not _is_pose(T_target):
            raise ArmError("IK target must be a finite 4x4 pose with a rotation matrix: check the planner")
        return pin.SE3(T_target[:3, :3], T_target[:3, 3])

    def _solve(
        self,
        oMdes: pin.SE3,
        q: np.ndarray,
        tol_pos: float,
        tol_rot: float,
        max_iter: int,
        q_rest: np.ndarray,
        posture_gain: float,
        lower: np.ndarray | None = None,
        upper: np.ndarray | None = None,
    ) -> tuple[np.ndarray, float, float]:
        """One damped-least-squares descent from q within [lower, upper] (default: the joint limits), plus
        posture_gain (q_rest - q) in the pose's null space while the error is above IK_POSTURE_UNTIL
        tolerances: (q, position error m, rotation error rad).

        Gives up early when the error has not shrunk by IK_STALL_RATIO over IK_STALL_WINDOW iterations
        (stuck against joint limits), so that a restart gets the time instead.
        """
        lower = self.model.lowerPositionLimit if lower is None else lower
        upper = self.model.upperPositionLimit if upper is None else upper
        history: list[float] = []
        for i in range(max_iter + 1):
            oMcur = self._placement(q)
            cMd = oMcur.actInv(oMdes)
            pos_err = float(np.linalg.norm(oMdes.translation - oMcur.translation))
            rot_err = float(np.linalg.norm(pin.log3(cMd.rotation)))
            err = pin.log6(cMd).vector
            history.append(float(np.linalg.norm(err)))
            stalled = i >= IK_STALL_WINDOW and history[-1] > IK_STALL_RATIO * history[-1 - IK_STALL_WINDOW]
            if (pos_err <= tol_pos and rot_err <= tol_rot) or i == max_iter or stalled:
                break
            J = -pin.Jlog6(cMd.inverse()) @ pin.computeFrameJacobian(
                self.model, self.data, q, self._frame_id, pin.LOCAL
            )
            far = pos_err > IK_POSTURE_UNTIL * tol_pos or rot_err > IK_POSTURE_UNTIL * tol_rot
            posture = posture_gain * (q_rest - q) if posture_gain and far else None
            dq = _dls_step(J, err, posture)
            blocked = ((q <= lower) & (dq < 0)) | ((q >= upper) & (dq > 0))
            if blocked.any():  # joints at a bound drop out, the others make up for them
                dq = _dls_step(J * ~blocked, err, None if posture is None else posture * ~blocked)
            dq *= min(1.0, IK_STEP_LIMIT / max(float(np.abs(dq).max()), 1e-12))
            q = np.clip(pin.integrate(self.model, q, dq), lower, upper)
        return q, pos_err, rot_err

    def solve_path(self, poses: Sequence[np.ndarray], q_seed: np.ndarray, **ik_options) -> np.ndarray:
        """Joint positions (N, dof) along a Cartesian path, each IK warm-started from the previous one.

        The redundancy is pulled toward q_seed all along (or `q_rest` in ik_options). Only the first
        waypoint may use random restarts; later ones must follow continuously, so a waypoint that does
        not converge or that needs a jump of more than PATH_MAX_JOINT_STEP_RAD raises IKError naming it.
        """
        qs = np.empty((len(poses), self.dof))
        q = np.asarray(q_seed, float)
        ik_options = {"q_rest": q, **ik_options}
        for i, pose in enumerate(poses):
            options = ik_options if i == 0 else {**ik_options, "restarts": 0}
            try:
                q_next = self.ik(pose, q, **options)
            except ArmError as exc:
                raise IKError(f"path waypoint {i} of {len(poses)} is not reachable: {exc}") from exc
            jump = np.abs(q_next - q)
            if i > 0 and jump.max() > PATH_MAX_JOINT_STEP_RAD:
                j = int(jump.argmax())
                raise IKError(
                    f"path waypoint {i} of {len(poses)} needs joint {self.joint_names[j]} to jump "
                    f"{jump[j]:.2f} rad (IK changed branch): the path passes near a singularity or a joint "
                    "limit; start from another arm configuration or shorten the path"
                )
            qs[i] = q = q_next
        return qs


def _urdf_model(path: Path) -> pin.Model:
    """Pinocchio's model of the URDF at `path`; ArmError naming the file when it is not one."""
    if path.is_dir():
        raise ArmError(f"robot URDF {path} is a directory, not a file (`urdf` empty?): give the path of the arm's "
                       ".urdf file")
    if not path.is_file():
        raise ArmError(f"robot URDF {path} does not exist: check the robot model path")
    fix = "give the path of the arm's .urdf file (XML with a <robot> root)"
    try:
        root = ElementTree.parse(path).getroot().tag
    except (ElementTree.ParseError, UnicodeDecodeError) as exc:
        raise ArmError(f"robot URDF {path} is not XML ({exc}): {fix}") from None
    if root != "robot":
        raise ArmError(f"robot URDF {path} has root <{root}>, not <robot>: {fix}")
    try:
        return pin.buildModelFromUrdf(str(path))
    except ValueError as exc:
        raise ArmError(f"robot URDF {path} is not a valid URDF model ({exc}): {fix}") from None


def _dls_step(J: np.ndarray, err: np.ndarray | None, posture: np.ndarray | None = None) -> np.ndarray:
    """Joint step -J^+ err + (I - J^+ J) posture with damped pseudo-inverses J^T (J J^T + lambda I)^-1.

    For the pose, lambda grows as the smallest singular value of J drops below IK_SINGULAR_VALUE
    (adaptive damping); the null-space projector keeps lambda = IK_DAMPING, so that the posture only
    moves the arm where that leaves the pose unchanged.
    """
    s_sq, W = np.linalg.eigh(J @ J.T)  # J J^T = W diag(s^2) W^T
    s_sq = np.maximum(s_sq, 0.0)
    y = np.zeros(len(s_sq))
    if err is not None:
        damping = IK_DAMPING + IK_SINGULAR_DAMPING * max(0.0, 1.0 - s_sq[0] / IK_SINGULAR_VALUE**2)
        y += (W.T @ err) / (s_sq + damping)
    if posture is None:
        return -J.T @ (W @ y)
    y += (W.T @ (J @ posture)) / (s_sq + IK_DAMPING)
    return posture - J.T @ (W @ y)


def well_conditioned_start(
    kin: Kinematics, poses: Sequence[np.ndarray], q_template: np.ndarray, margin_rad: float = 0.1,
    swung: bool = False,
) -> np.ndarray | None:
    """Joints at poses[0] from which every pose of the sequence is reached continuously, clear of the joint
    limits by `margin_rad`, choosing among a few seeds (`_start_seeds`, or with `swung` the elbow swung out
    sideways, `_sideways_seeds`) the one whose path stays farthest from singularities (largest smallest singular
    value of the Jacobian). A redundant arm needs this: per-tick IK started near a singularity turns joints 1 and 3
    fast. None when no seed works."""
    first, q_template = poses[0][:3, 3], np.array(q_template, float)
    seeds = _sideways_seeds(kin, first, q_template) if swung else _start_seeds(kin, first, q_template)
    best, best_score = None, -np.inf
    for seed in seeds:
        try:
            qs = kin.solve_path(poses, seed, restarts=0)
        except ArmError:
            continue
        if np.any(qs < kin.q_min + margin_rad) or np.any(qs > kin.q_max - margin_rad):
            continue
        score = min(np.linalg.svd(kin.jacobian(q), compute_uv=False)[-1] for q in qs)
        if score > best_score:
            best, best_score = qs[0], score
    return best


def grasps_grip(kin: Kinematics, q_template: np.ndarray, grip: np.ndarray, normal: np.ndarray, pitch_rad: float,
                approach_m: float, pull_m: float, steps: int = 6) -> bool:
    """Whether the arm reaches a handle's `grip` on a front facing `normal` (horizontal, outward) as the grasp planner
    takes it: approached `approach_m` straight in tilted down by `pitch_rad`, grasped across a vertical or a
    horizontal bar, and pulled `pull_m` straight out, clear of the joint limits (`well_conditioned_start`)."""
    normal = np.asarray(normal, float)
    for bar in (UP, np.cross(UP, normal)):
        T = grasp_pose(grip, normal, bar, GRASP_DEPTH_M, pitch_rad)
        approach = approach_poses(T, approach_m, steps)
        pull = [T.copy() for _ in range(steps)]
        for k, P in enumerate(pull, 1):
            P[:3, 3] += normal * pull_m * k / steps
        if well_conditioned_start(kin, [*approach, T, *pull], q_template, LIMIT_MARGIN_RAD) is not None:
            return True
    return False


def _start_seeds(kin: Kinematics, first: np.ndarray, q_template: np.ndarray) -> list[np.ndarray]:
    """Elbow seeds facing `first` for an arm whose first joint turns about the vertical and whose fourth is the
    elbow (the Panda's layout: the first joint toward the point, the second at -0.6, 0 or 0.6 rad, the fourth at
    -2.6 or -1.9 rad), those of them that lie within the joint limits; when none does (another layout, such as
    OpenArm's shoulder), the template and GENERIC_SEEDS fixed draws around it (GENERIC_SPREAD_RAD per joint, within
    the limits): postures like the arm's own start, not whatever IK reaches first."""
    seeds = _within_limits(kin, q_template, itertools.product((-0.6, 0.0, 0.6), (-2.6, -1.9)), first, 0.0, 0.0)
    if seeds:
        return seeds
    draws = np.random.default_rng(0).normal(0.0, GENERIC_SPREAD_RAD, (GENERIC_SEEDS, kin.dof))
    return [q_template, *np.clip(q_template + draws, kin.q_min, kin.q_max)]


def _sideways_seeds(kin: Kinematics, first: np.ndarray, q_template: np.ndarray) -> list[np.ndarray]:
    """Seeds of the Panda's layout (`_start_seeds`) with the elbow swung out to either side: the first joint
    SIDEWAYS_TURN_RAD off the line toward `first`, the second leaning SIDEWAYS_LEAN_RAD that way and the third turned
    SIDEWAYS_TWIST_RAD back, the wrist (joints 5 and 6) as in the template or bent at SIDEWAYS_WRIST_RAD either way.
    The second joint then stays clear of zero, where the first and third joints' axes line up (the shoulder's
    singularity that a point ahead and above the shoulder brings the usual seeds near), and the forearm comes at the
    hand from beside and below: a hand tilted up (under a counter's overhang), which the usual postures reach only
    with the wrist (joint 6) past its upper limit."""
    seeds = []
    for side, wrist in itertools.product((1.0, -1.0), (None, *SIDEWAYS_WRIST_RAD)):
        template = q_template.copy()
        if wrist is not None:
            template[4:6] = wrist
        seeds += _within_limits(kin, template, [(side * SIDEWAYS_LEAN_RAD, -1.9)], first,
                                side * SIDEWAYS_TURN_RAD, -side * SIDEWAYS_TWIST_RAD)
    return seeds


def _within_limits(kin: Kinematics, q_template: np.ndarray, shoulder_elbow, first: np.ndarray, turn: float,
                   twist: float) -> list[np.ndarray]:
    """The template with joints 1-4 at (the direction of `first` + turn, q2, twist, q4) for each (q2, q4), those
    within the joint limits."""
    seeds = []
    for q2, q4 in shoulder_elbow:
        seed = q_template.copy()
        seed[:4] = np.arctan2(first[1], first[0]) + turn, q2, twist, q4
        if np.all(seed >= kin.q_min) and np.all(seed <= kin.q_max):
            seeds.append(seed)
    return seeds


def _is_pose(T: np.ndarray) -> bool:
    """A finite 4x4 transform whose rotation block is a proper rotation."""
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        return False
    R = T[:3, :3]
    return bool(np.abs(R.T @ R - np.eye(3)).max() <= 1e-5 and np.linalg.det(R) > 0)
