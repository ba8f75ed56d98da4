"""`deploy open*` end to end: joint auto, --dry-run, --view, --arm sim-can, and the hardware path on a
recording with the kinematic arm; bad combinations are one clear error."""

import json
import re

import pytest
from rerun_files import entities

from deploy.cli import main
from deploy.control.state import StopReason

ROBOT = "panda_sim"  # a shipped robot config, by name


def run(capsys, *args):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize(("scene", "joint"), [("door", "revolute"), ("drawer", "prismatic")])
def test_open_auto_classifies_and_opens(capsys, tmp_path, scene, joint):
    code, out, err = run(capsys, "open", "--world", "box", "--joint", "auto", "--task", scene, "--split", "test",
                         "--seed", "1", "--distance", "0.12", "--angle", "20", "--run-dir", tmp_path / "run", "--json")
    data = json.loads(out)
    assert code == 0 and data["success"] and data["axis"]["joint_type"] == joint
    assert re.search(rf"probe pull: the front turned -?[\d.]+ deg and moved -?[\d.]+ m out: a {scene} \({joint}\)", err)
    steps = json.loads((tmp_path / "run" / "steps.json").read_text())
    probe = [s for s in steps["steps"] if s["source"] == "probe pull"]
    assert probe[0]["classified"] == joint


def test_dry_run_plans_moves_nothing_and_views(capsys, tmp_path):
    code, out, _ = run(capsys, "open-door", "--world", "box", "--dry-run", "--view", "--run-dir", tmp_path / "run",
                       "--json")
    data = json.loads(out)
    assert code == 0 and data["stop_reason"] == StopReason.DRY_RUN and "nothing moved" in data["message"]
    assert abs(data["true_opened_deg"]) < 0.2 and data["steps"] == 0
    assert (tmp_path / "run" / "episode.rrd").stat().st_size > 10_000  # frame, cloud and gripper pose logged
    found = entities(tmp_path / "run" / "episode.rrd")
    assert "Pinhole:image_from_camera" in found["/world/camera/image"]["components"]  # images sit in 3D
    assert found["/world/axis/true"]["rows"] == 1 and "/world/object/first" in found


def test_sim_can_arm_opens_through_the_can_driver(capsys, tmp_path):
    code, out, _ = run(capsys, "open-drawer", "--world", "box", "--arm", "sim-can", "--distance", "0.1", "--run-dir",
                       tmp_path / "r", "--json")
    data = json.loads(out)
    assert code == 0 and data["success"] and data["true_opened_m"] >= 0.1


def test_hardware_path_on_a_recording_with_the_kinematic_arm(capsys, tmp_path):
    rec = tmp_path / "rec"
    assert main(["sim", "record", "--world", "box", "--task", "drawer", "--seed", "0", "--fps", "2", "--out", str(rec),
                 "--json"]) == 0
    recorded = json.loads(capsys.readouterr().out)
    assert recorded["frames"] >= 10 and recorded["target_m"] == 0.2 and recorded["opened_m"] > 0.15
    code, out, _ = run(capsys, "open-drawer", "--camera", f"replay:{rec}", "--arm", "ideal", "--robot", ROBOT,
                       "--segmenter", "oracle", "--dry-run", "--run-dir", tmp_path / "run", "--json")
    data = json.loads(out)
    assert code == 0 and data["stop_reason"] == StopReason.DRY_RUN and data["arm"] == "ideal"
    assert data["axis"]["joint_type"] == "prismatic" and data["axis"]["direction"][0] < -0.9  # toward the robot


@pytest.mark.parametrize(("args", "text"), [
    (("--camera", "d415", "--arm", "sim"), "--arm sim needs --camera sim"),
    (("--camera", "sim", "--arm", "can"), "--camera sim needs a simulated arm"),
    (("--camera", "replay:/nonexistent"), "is a recording: it cannot show what the arm does, so an opening on it can "
                                          "only be planned: add --dry-run (without hardware: --arm ideal"),
    (("--camera", "replay:/nonexistent", "--arm", "can", "--robot", "damiao_6dof"), "add --dry-run"),
    (("--camera", "replay:/nonexistent", "--arm", "ideal", "--robot", ROBOT), "add --dry-run"),
    (("--camera", "replay:/nonexistent", "--dry-run"), "to replay a recording without hardware: --arm ideal --robot "
                                                        "panda_sim"),
    (("--calibration-error", "1000", "0"), "1000 mm 0 deg is outside 0-100 mm and 0-10 deg"),
    (("--camera", "replay:/nonexistent", "--arm", "can", "--dry-run"), "--arm can needs --robot"),
    (("--segmenter", "classical"), "the classical segmenter needs the object's box on the first frame"),
    (("--camera", "webcam", "--arm", "ideal", "--robot", ROBOT), "unknown camera 'webcam'"),
    (("--camera", "d415", "--arm", "ideal", "--robot", ROBOT, "--segmenter", "oracle"),
     "no RealSense camera is connected"),
    (("--camera", "d415", "--arm", "ideal", "--robot", ROBOT, "--condition", "locked"),
     "--condition locked is for a simulated scene"),
])
def test_bad_combinations_are_one_clear_error(capsys, args, text):
    code, _, err = run(capsys, "open-drawer", *args)
    assert code == 2 and text in " ".join(err.split())
