"""Forward and inverse kinematics of the arm's tool frame with Pinocchio (URDF, no meshes)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from drivers.arm.robots import RobotSpec, panda
from drivers.errors import ArmError

IK_STEP_LIMIT = 1.0  # rad: largest joint change per iteration, keeps early steps from overshooting
IK_DAMPING = 1e-6  # damped least squares: J^T (J J^T + lambda I)^-1
IK_STALL_WINDOW, IK_STALL_RATIO = 20, 0.9  # give up when 20 iterations shrink the error < 10 %
PATH_MAX_JOINT_STEP_RAD = 0.5  # a larger jump between path waypoints means IK switched branch


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
        if not path.is_file():
            raise ArmError(f"robot URDF {path} does not exist: check the robot model path")
        full = pin.buildModelFromUrdf(str(path))
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
    ) -> np.ndarray:
        """Joint positions reaching tool pose `T_target` (tolerances in m and rad), nearest `q_seed` first.

        Damped least squares on log6(oMcurrent^-1 * oMdesired), clamped to the joint limits; when the
        seed does not converge, up to `restarts` random seeds within the limits are tried (from `rng`,
        default a fixed seed, so equal inputs give equal answers). Raises ArmError when none converges.
        """
        T_target = np.asarray(T_target, float)
        if not _is_pose(T_target):
            raise ArmError("IK target must be a finite 4x4 pose with a rotation matrix: check the planner")
        oMdes = pin.SE3(T_target[:3, :3], T_target[:3, 3])
        q = np.clip(np.asarray(q_seed, float), self.q_min, self.q_max)
        rng = np.random.default_rng(0) if rng is None else rng
        best_pos_err, best_rot_err = np.inf, np.inf
        for attempt in range(restarts + 1):
            if attempt > 0:
                q = rng.uniform(self.q_min, self.q_max)
            q, pos_err, rot_err = self._solve(oMdes, q, tol_pos, tol_rot, max_iter)
            if pos_err <= tol_pos and rot_err <= tol_rot:
                return q
            if pos_err < best_pos_err:
                best_pos_err, best_rot_err = pos_err, rot_err
        p = T_target[:3, 3]
        raise ArmError(
            f"target pose unreachable: tool at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m in the base frame "
            f"(position error {best_pos_err * 1e3:.1f} mm, rotation error {np.degrees(best_rot_err):.1f} deg "
            f"after {restarts + 1} attempts); move the object closer or change the grasp orientation"
        )

    def _solve(
        self, oMdes: pin.SE3, q: np.ndarray, tol_pos: float, tol_rot: float, max_iter: int
    ) -> tuple[np.ndarray, float, float]:
        """One damped-least-squares descent from q: (q, position error m, rotation error rad).

        Gives up early when the error has not shrunk by IK_STALL_RATIO over IK_STALL_WINDOW iterations
        (stuck against joint limits), so that a restart gets the time instead.
        """
        q_min, q_max = self.model.lowerPositionLimit, self.model.upperPositionLimit
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
            dq = self._dls_step(J, err)
            blocked = ((q <= q_min) & (dq < 0)) | ((q >= q_max) & (dq > 0))
            if blocked.any():  # joints at a limit drop out, the others make up for them
                dq = self._dls_step(J * ~blocked, err)
            dq *= min(1.0, IK_STEP_LIMIT / max(float(np.abs(dq).max()), 1e-12))
            q = np.clip(pin.integrate(self.model, q, dq), q_min, q_max)
        return q, pos_err, rot_err

    @staticmethod
    def _dls_step(J: np.ndarray, err: np.ndarray) -> np.ndarray:
        return -J.T @ np.linalg.solve(J @ J.T + IK_DAMPING * np.eye(6), err)

    def solve_path(self, poses: Sequence[np.ndarray], q_seed: np.ndarray, **ik_options) -> np.ndarray:
        """Joint positions (N, dof) along a Cartesian path, each IK warm-started from the previous one.

        Only the first waypoint may use random restarts; later ones must follow continuously, so a
        waypoint that does not converge or that needs a jump of more than PATH_MAX_JOINT_STEP_RAD
        raises ArmError naming it.
        """
        qs = np.empty((len(poses), self.dof))
        q = np.asarray(q_seed, float)
        for i, pose in enumerate(poses):
            options = ik_options if i == 0 else {**ik_options, "restarts": 0}
            try:
                q_next = self.ik(pose, q, **options)
            except ArmError as exc:
                raise ArmError(f"path waypoint {i} of {len(poses)} is not reachable: {exc}") from exc
            jump = np.abs(q_next - q)
            if i > 0 and jump.max() > PATH_MAX_JOINT_STEP_RAD:
                j = int(jump.argmax())
                raise ArmError(
                    f"path waypoint {i} of {len(poses)} needs joint {self.joint_names[j]} to jump "
                    f"{jump[j]:.2f} rad (IK changed branch): the path passes near a singularity or a joint "
                    "limit; start from another arm configuration or shorten the path"
                )
            qs[i] = q = q_next
        return qs


def _is_pose(T: np.ndarray) -> bool:
    """A finite 4x4 transform whose rotation block is a proper rotation."""
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        return False
    R = T[:3, :3]
    return bool(np.allclose(R.T @ R, np.eye(3), atol=1e-6) and np.linalg.det(R) > 0)
