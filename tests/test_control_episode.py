"""End-to-end opening episodes in simulation: the policy sees the camera and the arm only; the tests
read the world's truth to judge the outcome and, for stop conditions, change the world first."""

import json
from dataclasses import replace

import numpy as np
import pybullet as pb
import pytest
from episodes import sim_episode

from deploy.bench.open import bench_open, simulate_episode
from deploy.config import Config
from deploy.control.session import OpenRequest, open_object
from deploy.control.state import StopReason
from deploy.estimate_recording import estimate_recording
from deploy.perception.oracle import OracleSegmenter
from deploy.report.run_folder import RunFolder
from drivers.camera.frames_dir import FramesRecording
from sim_fallback.scenario import Scenario

STOP_REASONS = set(StopReason) - {StopReason.DRY_RUN, StopReason.INTERRUPTED}  # how an opening can end


def test_drawer_closed_loop_opens_and_its_run_folder_replays(tmp_path):
    result = simulate_episode("drawer", 0, "train", target=0.15, run_dir=tmp_path / "run", world="box")
    assert result["stop_reason"] == StopReason.TARGET_REACHED
    assert result["success"] and result["true_opened_m"] >= 0.15
    assert abs(result["opened_m"] - result["true_opened_m"]) < 0.01  # progress from kinematics is honest
    assert result["axis"]["joint_type"] == "prismatic" and result["axis_angle_error_deg"] < 8
    json.dumps(result)
    run = tmp_path / "run"
    steps = json.loads((run / "steps.json").read_text())
    assert len(steps["steps"]) == result["steps"] + 1 and steps["motions"][0]["label"] == "first pull"
    for before, motion in zip(steps["motions"], steps["motions"][1:], strict=False):  # one episode clock
        assert motion["start_s"] >= before["start_s"] + before["t"][-1]
    assert all(s["axis_position_error_m"] is None for s in steps["steps"])  # a drawer's axis is a direction
    assert any(s["axis_angle_error_deg"] is not None for s in steps["steps"])
    assert (run / "report.png").stat().st_size > 10_000
    replay = estimate_recording(run / "frames", Config())
    assert replay["n_samples"] >= 5 and replay["joint_type"] == "prismatic"
    records = FramesRecording(run / "frames").records
    assert [r["grasped"] for r in records] == [not r.get("first") for r in records]  # first frames, then pulls'
    assert records[0]["grasped"] is False and replay["gripper_frames"] == sum(r["grasped"] for r in records)


def test_a_run_that_looked_again_replays_from_where_it_looked(tmp_path):
    """Test drawer 1: the arm hid the cabinet on the first frame, swung out of the view and looked again. The
    replay starts its pipeline over at that second first frame, as the run did, so it computes the axis the run
    acted on (the paper's estimator, acted on alone); from the first frame's body box it computed another."""
    result = simulate_episode("drawer", 1, "test", target=0.10, policy="paper", run_dir=tmp_path / "run", world="box")
    frames = tmp_path / "run" / "frames"
    records = FramesRecording(frames).records
    assert [r["index"] for r in records if r.get("first")] == [0, 1]
    steps = json.loads((tmp_path / "run" / "steps.json").read_text())["steps"]
    acted = next(s for s in steps if s["source"] == "vision")  # the first step acted on what vision estimated
    replay = estimate_recording(frames, Config().replace(estimator={"name": "paper-obb", "joint": "prismatic"}))
    directions = [s["direction"] for s in replay["steps"] if s["direction"] is not None]
    assert any(np.allclose(d, acted["axis"]["direction"], atol=1e-6) for d in directions), result["message"]


@pytest.mark.parametrize(("seed", "split"), [(1, "train"), (0, "test")])
def test_door_closed_loop_opens(seed, split):
    result = simulate_episode("door", seed, split, target=30.0, world="box")
    assert result["stop_reason"] == StopReason.TARGET_REACHED, result["message"]
    assert result["success"] and result["true_opened_deg"] >= 30.0
    assert result["axis"]["joint_type"] == "revolute"
    assert result["axis_angle_error_deg"] < 10 and result["axis_position_error_m"] < 0.05


@pytest.mark.parametrize(("task", "policy", "target", "seed"),
                         [("drawer", "open", 0.15, 2), ("door", "paper", 20.0, 1)])
def test_open_loop_and_paper_policies_run(task, policy, target, seed):
    """(Train door 2's friction grip loses the paper's straight steps: that policy's failure, not its plumbing.)"""
    result = simulate_episode(task, seed, "train", target=target, policy=policy, world="box")
    assert result["policy"] == policy and result["stop_reason"] in STOP_REASONS
    unit = "m" if task == "drawer" else "deg"
    assert result[f"true_opened_{unit}"] > 0.3 * target, result["message"]


class _LosingSegmenter(OracleSegmenter):
    """Finds the object on the first frame, then loses it (as a tracker does when the view is blocked)."""

    def start(self, frame, prompt="cabinet", pointer=None):
        return super().track(frame)

    def track(self, frame):
        return np.zeros_like(super().track(frame))


def test_locked_drawer_ends_blocked_and_safe():
    def lock(world, arm):
        pb.setJointMotorControl2(world.cabinet_id, world.cabinet_joint, pb.VELOCITY_CONTROL, targetVelocity=0.0,
                                 force=1e5, physicsClientId=world.client)
        arm.grasp_force_limit_n = 1e5  # the grasp holds, so the arm itself feels the lock

    ran = sim_episode(setup=lock)
    result, still = ran.result, ran.still
    assert result.stop_reason is StopReason.BLOCKED and "no more motion" in result.message
    assert not result.success and still


def test_slipping_grasp_regrasps_once_then_fails_clearly(tmp_path):
    def weaken(world, arm):  # a weak weld and a frictionless handle: the fingers slide off
        arm.grasp_force_limit_n = 0.5
        pb.changeDynamics(world.cabinet_id, world.handle_link, lateralFriction=0.0, physicsClientId=world.client)

    ran = sim_episode(setup=weaken, folder=RunFolder(tmp_path / "run"))
    result, still = ran.result, ran.still
    assert result.stop_reason is StopReason.GRASP_LOST and result.regrasped  # held at first, slipped, re-grasped once
    assert result.message.startswith("the handle slipped out of the gripper again during ")
    assert "after one re-grasp: the pull needs more force than the grasp holds" in result.message
    assert not result.success and still
    assert json.loads(json.dumps(result.to_dict()))["stop_reason"] == result.stop_reason
    records = FramesRecording(tmp_path / "run" / "frames").records
    held = [r["grasped"] for r in records]  # the first frame; each pull's while held and, after each slip, not
    assert held[0] is False and held[1] is True and held.count(False) >= 3 and held[-1] is False


def test_a_slip_is_recovered_by_finding_the_handle_again():
    def slip_once(world, arm):  # weak and frictionless until the gripper has slipped off and opened again
        arm.grasp_force_limit_n = 0.5
        pb.changeDynamics(world.cabinet_id, world.handle_link, lateralFriction=0.0, physicsClientId=world.client)
        seen = {"slipped": False}

        def restore():
            width = arm.state().gripper_width_m
            seen["slipped"] |= width < 0.003
            if seen["slipped"] and width > 0.03 and arm.grasp_force_limit_n is not None:
                arm.grasp_force_limit_n = None  # the gripping force's friction again
                pb.changeDynamics(world.cabinet_id, world.handle_link, lateralFriction=1.0,
                                  physicsClientId=world.client)

        world.clock.add_hook(restore)

    ran = sim_episode(setup=slip_once, target=0.15)
    result, still = ran.result, ran.still
    assert result.stop_reason is StopReason.TARGET_REACHED and result.success and still
    assert result.regrasped and result.opened >= 0.15


def test_a_drawer_that_slides_back_after_a_slip_is_found_again_along_its_path():
    """The grip breaks 16 cm out and the drawer slides back in to 2 cm (a soft-close drawer), beyond the 12 cm the
    re-grasp looks in around where it held: the handle is found back along the estimated axis and the opening
    counts from there (counted from before the slip, the loop would stop 14 cm short believing the target
    reached)."""
    seen = {"slid": False, "value": 0.0}

    def slip_then_slide_back(world, arm):
        def hook():
            seen["value"] = world.joint_value()
            if not seen["slid"] and seen["value"] > 0.16 and arm._grip is not None:
                arm._release()  # the grip breaks (the fingers close on nothing) ...
                pb.resetJointState(world.cabinet_id, world.cabinet_joint, 0.02, physicsClientId=world.client)
                seen["slid"] = True  # ... and the drawer is back in

        world.clock.add_hook(hook)

    ran = sim_episode(setup=slip_then_slide_back, target=0.30)
    result, still = ran.result, ran.still
    assert seen["slid"] and result.regrasped
    assert result.stop_reason is StopReason.TARGET_REACHED and still, result.message
    assert seen["value"] >= 0.30 and abs(result.opened - seen["value"]) < 0.02


def test_lost_tracking_stops_safely():
    ran = sim_episode(segmenter=_LosingSegmenter())
    result, still = ran.result, ran.still
    assert result.stop_reason is StopReason.TRACKING_LOST and "mask shrank to 0 pixels" in result.message
    assert not result.success and still


def test_unreachable_handle_is_refused_before_moving():
    scenario = Scenario.make("drawer", 0, "train")
    far = replace(scenario, cabinet_xy=tuple(1.6 * np.array(scenario.cabinet_xy)))  # the handle ~1 m away
    ran = sim_episode(target=0.30, scenario=far)
    result, still = ran.result, ran.still
    assert result.stop_reason is StopReason.IK_INFEASIBLE and "out of reach" in result.message
    assert result.steps == 0 and still


def test_bench_open_reports_the_issue_keys():
    out = bench_open("drawer", 0.1, episodes=1, split="train", seed=0, first_pull_m=0.05, max_steps=2, world="box")
    assert set(out) >= {"task", "target_m", "split", "policy", "episodes", "success_rate", "mean_opened_m",
                        "axis_angle_error_deg_median", "seconds_per_episode", "failures"}
    assert out["success_rate"] == 1.0 and out["mean_opened_m"] >= 0.1 and out["failures"] == {}
    # a frame's CPU time on its thread is positive and never more than the wall time it took
    assert 0 < out["frame_cpu_ms_median"] <= out["frame_ms_median"] * 1.01
    json.dumps(out)



def test_a_target_nearer_than_the_first_pull_is_not_overshot_by_it():
    """The first pull stops at the steps' goal (target + 1.5 cm): a 1 cm target is not pulled the whole 5 cm."""
    result = simulate_episode("drawer", 0, "test", target=0.01, world="box")
    assert result["success"] and result["stop_reason"] == StopReason.TARGET_REACHED, result["message"]
    assert 0.01 <= result["true_opened_m"] < 0.035



def test_a_dry_run_commands_no_motion_even_when_the_arm_hides_the_object(tmp_path, caplog):
    """The default start pose hides part of the drawer: a run swings joint 1 out of the view first, a dry run
    only says so (it had swung the arm, without the confirmation a run asks for)."""
    moved = []

    def spy(_world, arm):
        start, command = arm.state().q.copy(), arm.command

        def watched(q, dq=None):
            moved.append(float(np.abs(np.asarray(q) - start).max()))
            command(q, dq)

        arm.command = watched

    with caplog.at_level("INFO", logger="deploy.control.stages"):
        data = open_object(OpenRequest(task="drawer", scene="drawer", run_dir=tmp_path / "run", dry_run=True,
                                       world="box"), setup=spy)
    assert data["stop_reason"] == StopReason.DRY_RUN
    assert "dry run: the arm hides part of the object; a run would first turn panda_joint1" in caplog.text
    assert max(moved, default=0.0) < 1e-9


def test_a_door_pulled_by_the_force_cue_is_hinged_where_the_grip_point_turned_not_where_the_fingers_turned():
    """Test door 3: the pull strains, so the loop acts on the gripper's path. The handle turns in the fingers, so
    the gripper's own turn is not the door's; fitted with it, the hinge was 17 mm off and the door 3 deg short of
    where the loop believed it was."""
    result = simulate_episode("door", 3, "test", target=70.0, world="box")
    assert result["success"], result["message"]
    assert result["axis_position_error_m"] < 0.005
    assert abs(result["true_opened_deg"] - result["opened_deg"]) < 1.0


def test_a_door_of_a_pair_taken_for_one_front_turns_about_its_own_hinge():
    """Test kitchen door 30: the pointed front is a pair of doors, the handle by their meeting line in its middle.
    The far edge of that front is the other door's hinge: the first arc about it jammed the door at 19 deg. The first
    pull goes straight for 2.5 cm and the door's own motion tells its hinge's side."""
    result = simulate_episode("door", 30, "test", target=45.0)
    assert result["success"], result["message"]
    assert result["axis_position_error_m"] < 0.05


@pytest.mark.parametrize("seed", [51, 64])
def test_a_door_whose_hinge_prior_is_off_turns_about_the_hinge_its_front_turn_shows(seed):
    """Test kitchen doors 51 (a front found 1 m wide: the prior hinge 0.62 m beyond the true one) and 64 (the hinge's
    side unsure: the prior on the far side, 0.97 m off). The stiff arm drags the door along the prior's arc, so the
    gripper's path shows the prior; the first step jammed at 60 N across its arc (16-30 deg open). The closed front
    and the front the camera sees turned meet at the hinge."""
    result = simulate_episode("door", seed, "test", target=45.0)
    assert result["success"], result["message"]
    assert result["axis_position_error_m"] < 0.03
