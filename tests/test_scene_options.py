"""The simulated scene a command asks for (`--world`, `--part`, `--assets`, `--object`, `--scale`) and the pixel a
user points at (`--point`): one-line errors for bad input, PartNet-Mobility objects (made by the tests) recorded,
shown and benchmarked in a kitchen, and the pointer reaching the segmenter."""

import json

import numpy as np
import pytest
from cli_run import one_line, run, small_recording
from partnet_objects import Front, write_object

from deploy.control.session import OpenRequest, open_object
from deploy.errors import PerceptionError
from deploy.perception.base import Pointer
from deploy.perception.rgbd import RGBDSegmenter
from drivers.arm.robots import PANDA_REACH
from drivers.camera.base import Frame, Intrinsics
from sim_fallback.camera_scenes import look_along_x

# a drawer beside a door, both within the robot's reach once sized as a real refrigerator
SIDE_BY_SIDE = (Front("drawer", (-0.48, -0.01), (0.25, 0.58), label="drawer"),
                Front("door", (0.01, 0.48), (0.0, 0.58), label="rotation_door"))

LOW_DRAWER_UNDER_DOOR = (Front("drawer", (-0.48, 0.48), (-0.58, -0.3), label="drawer"),
                         Front("door", (-0.48, 0.48), (-0.25, 0.58), label="rotation_door"))


@pytest.fixture(autouse=True)
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


@pytest.fixture
def assets(tmp_path):
    """A folder of two objects: 12 with a drawer and a door in reach, 40 whose drawer stands too low for any grasp
    and whose door stands below the usual reach but within the reach from above."""
    folder = tmp_path / "assets"
    write_object(folder / "12", fronts=SIDE_BY_SIDE, category="Refrigerator")
    write_object(folder / "40", fronts=LOW_DRAWER_UNDER_DOOR)
    return folder


@pytest.mark.parametrize(("args", "text"), [
    (("--world", "garden"), "'garden' is not one of 'kitchen', 'box'"),
    (("--object", "12"), "--object 12 needs --assets DIR"),
    (("--world", "box", "--part", "top drawer"), "the box world's cabinet has one part"),
    (("--part", "cellar drawer"), "--part 'cellar drawer' is not one of its parts"),
    (("--point", "640", "10"), "--point 640 10 is off the camera's 640x480 image"),
    (("--camera", "d415", "--arm", "ideal", "--robot", "panda_sim", "--part", "top drawer"),
     "--part top drawer is for a simulated scene: drop it, or use --camera sim"),
])
def test_bad_scene_options_are_one_line(capsys, tmp_path, args, text):
    code, _, err = run(capsys, "open-drawer", *args, "--run-dir", tmp_path / "run")
    assert code == 2 and text in one_line(err)
    assert not (tmp_path / "run").exists()


def test_an_unknown_part_lists_the_parts_of_its_kind(capsys, tmp_path):
    code, _, err = run(capsys, "open-drawer", "--seed", "2", "--split", "test", "--part", "9", "--run-dir",
                       tmp_path / "run")
    assert code == 2 and "its drawers are 0 " in one_line(err) and "(link " in err


def test_bad_assets_are_one_line(capsys, tmp_path, assets):
    (tmp_path / "meshes").mkdir()
    cases = [(("--assets", tmp_path / "meshes"), "not in the PartNet-Mobility layout"),
             (("--assets", tmp_path / "nowhere"), "no such folder"),
             (("--assets", assets, "--object", "45213"), "object 45213 is not in"),
             (("--assets", assets, "--object", "12", "--part", "top shelf"),
              "--part 'top shelf' is not one of its parts in partnet 12: its drawers are 0 drawer (link link_1)"),
             (("--assets", assets, "--world", "box"), "--assets places PartNet-Mobility objects in a kitchen")]
    for args, text in cases:
        code, _, err = run(capsys, "open-drawer", *args, "--run-dir", tmp_path / "run")
        assert code == 2 and text in one_line(err), args
    broken = write_object(tmp_path / "broken" / "7")
    (broken / "textured_objs" / "original-3.obj").unlink()
    code, _, err = run(capsys, "sim", "show", "--assets", tmp_path / "broken", "--object", "7", "--out",
                       tmp_path / "s.png")
    assert code == 2 and "partnet 7" in one_line(err) and "textured_objs/original-3.obj" in err
    (broken / "mobility.urdf").write_text("not xml at all")
    code, _, err = run(capsys, "sim", "record", "--assets", tmp_path / "broken", "--object", "7", "--out",
                       tmp_path / "r")
    assert code == 2 and "partnet 7: mobility.urdf" in one_line(err) and not (tmp_path / "r").exists()


def test_sim_show_lists_the_objects_parts_and_renders_the_one_asked_for(capsys, tmp_path, assets):
    png = tmp_path / "scene.png"
    code, out, err = run(capsys, "sim", "show", "--assets", assets, "--object", "12", "--part", "door", "--out", png,
                         "--json")
    data = json.loads(out)
    assert code == 0, err
    assert data["world"] == "kitchen" and data["task"] == "door" and data["part"] == "door"
    assert data["furniture"] == "partnet 12" and png.stat().st_size > 10_000
    [entry] = data["objects"]
    assert entry["id"] == "12" and entry["problem"] is None and entry["unusable_for"] == {}
    assert [(p["name"], p["kind"], p["link"], p["unit"]) for p in entry["parts"]] == [
        ("drawer", "drawer", "link_1", "m"), ("door", "door", "link_2", "deg")]
    assert all(p["range"][0] == 0 and p["range"][1] > 0 for p in entry["parts"])
    code, out, _ = run(capsys, "sim", "show", "--assets", assets, "--task", "drawer", "--seed", "1", "--out", png,
                       "--overwrite", "--json")
    listed = {e["id"]: e for e in json.loads(out)["objects"]}
    assert code == 0 and listed["12"]["unusable_for"] == {} and listed["40"]["problem"] is None
    assert list(listed["40"]["unusable_for"]) == ["drawer"]
    assert "partnet 40 has no drawer within the robot's reach: its grips stand above the floor" in (
        listed["40"]["unusable_for"]["drawer"])


def test_sim_show_renders_an_object_that_serves_doors_only_with_its_door(capsys, tmp_path, assets):
    code, out, err = run(capsys, "sim", "show", "--assets", assets, "--object", "40", "--out", tmp_path / "40.png",
                         "--json")
    assert code == 0, err
    assert json.loads(out)["task"] == "door"


def test_an_object_with_no_part_in_the_usual_reach_is_usable_when_the_arm_grasps_it_from_above(assets):
    from sim_fallback.scenes import task_objects

    assert task_objects(assets, "door").usable == ("12", "40")
    low = task_objects(assets, "door", reach=PANDA_REACH.usual())
    assert low.usable == ("12",) and "partnet 40 has no door within the robot's reach" in low.problems["40"]
    assert "and from above" not in low.problems["40"]
    problem = task_objects(assets, "drawer").problems["40"]
    assert "and from above 0.40-1.70 m for a part named or when no grip is in that band" in problem


def test_a_kitchen_recording_of_a_partnet_object_opens_the_named_part(capsys, tmp_path, assets):
    out = tmp_path / "rec"
    code, printed, err = run(capsys, "sim", "record", "--assets", assets, "--object", "12", "--part", "drawer",
                             "--fps", "2", "--out", out, "--json")
    data = json.loads(printed)
    assert code == 0, err
    assert data["task"] == "drawer" and data["part"] == "drawer" and data["world"] == "kitchen"
    assert data["opened_m"] == pytest.approx(data["target_m"], abs=0.01)
    truth = json.loads((out / "truth.json").read_text())
    assert truth["furniture"] == "partnet 12" and truth["object"] == "12" and truth["scale"] == "real"
    assert truth["joint_type"] == "prismatic" and truth["joint_values"][-1] > 0.19


def test_a_low_door_is_recorded_grasped_from_above(capsys, tmp_path, assets):
    """Object 40's door stands below the arm's usual reach: the scripted grasp takes it from above and opens it."""
    out = tmp_path / "rec"
    code, printed, err = run(capsys, "sim", "record", "--assets", assets, "--object", "40", "--part", "door",
                             "--fps", "2", "--out", out, "--json")
    assert code == 0, err
    truth = json.loads((out / "truth.json").read_text())
    assert truth["joint_type"] == "revolute" and truth["joint_values"][-1] > 0.4


def test_bench_open_reports_per_object_and_part_with_the_scene_and_sensors(tmp_path, assets):
    from deploy.bench.open import bench_open

    data = bench_open("drawer", 0.1, episodes=2, split="train", seed=0, segmenter="rgbd", assets=assets,
                      max_steps=1)
    assert data["world"] == "kitchen" and data["assets"] == str(assets) and data["scale"] == "real"
    assert data["part"] is None and data["pointer"].startswith("simulated user")
    assert set(data["sensors"]) == {"depth", "torque_sensing", "pad_friction_range"}
    assert data["sensors"]["depth"] == "D415 artefact model" and data["sensors"]["pad_friction_range"] == [0.4, 0.8]
    assert list(data["objects"]) == ["12"] and data["objects"]["12"]["episodes"] == 2
    assert list(data["objects"]["12"]["parts"]) == ["drawer"] and data["per_part"]["drawer"]["episodes"] == 2
    assert "no drawer within the robot's reach" in data["unusable_objects"]["40"]
    counted = sum(data["failures"].values()) + round(data["success_rate"] * 2)
    assert counted == 2 and sum(data["objects"]["12"]["failures"].values()) == 2 - data["objects"]["12"]["successes"]


def test_the_pointer_reaches_the_pointed_part_finder_and_the_box_world_has_none(monkeypatch, tmp_path):
    """--point goes to the pointed-part finder (deploy/perception/pointing.py), not the segmenter; the box world (one
    cabinet in empty space, the paper's setting) has no simulated user and its segmenter starts without a pointer."""
    from deploy.control import observer

    started, pointed = [], []
    real_start, real_point_at = RGBDSegmenter.start, observer.point_at

    def start(self, frame, prompt=None, pointer=None):
        started.append(pointer)
        return real_start(self, frame, prompt, pointer)

    def point_at(frame, robot, pointer, **kwargs):
        pointed.append(pointer)
        return real_point_at(frame, robot, pointer, **kwargs)

    monkeypatch.setattr(RGBDSegmenter, "start", start)
    monkeypatch.setattr(observer, "point_at", point_at)
    data = open_object(OpenRequest(task="drawer", dry_run=True, segmenter="rgbd", point=(300.0, 250.0),
                                   run_dir=tmp_path / "run"))
    assert pointed == [Pointer(300.0, 250.0)] and started == []
    assert data["pointer"] == {"u": 300.0, "v": 250.0, "source": "--point"}
    config = json.loads((tmp_path / "run" / "config.json").read_text())
    assert config["perception"]["point"] == [300.0, 250.0] and config["scene"]["pointer"]["source"] == "--point"
    assert config["scene"]["world"] == "kitchen" and config["scene"]["sensors"]["depth"] == "D415 artefact model"
    box = open_object(OpenRequest(task="drawer", world="box", dry_run=True, segmenter="rgbd"), keep_run_dir=False)
    assert box["pointer"] is None and started == [None] and len(pointed) == 1


def test_rgbd_detects_the_furniture_the_pointer_shows():
    """Two pieces 1 m in front of the camera: without a pointer the larger, with one the piece it is on."""
    K = Intrinsics.from_fov(320, 240, 65.0)
    depth = np.zeros((240, 320), np.float32)
    depth[40:200, 20:180] = 1.0  # the larger piece, on the left of the image
    depth[40:200, 220:300] = 1.0
    frame = Frame(0, 0.0, np.zeros((240, 320, 3), np.uint8), depth, K, look_along_x(1.0))
    largest = RGBDSegmenter().start(frame)
    assert largest[120, 100] and not largest[120, 260]
    pointed = RGBDSegmenter().start(frame, pointer=Pointer(260, 120))
    assert pointed[120, 260] and not pointed[120, 100]
    with pytest.raises(PerceptionError, match="no depth at the pointed pixel"):
        RGBDSegmenter().start(frame, pointer=Pointer(200, 10))


def test_a_point_off_a_recordings_image_is_one_line(capsys, tmp_path):
    recording = small_recording(tmp_path / "rec")  # 160x120
    code, _, err = run(capsys, "open-drawer", "--camera", f"replay:{recording}", "--arm", "ideal", "--robot",
                       "panda_sim", "--dry-run", "--point", "200", "50", "--run-dir", tmp_path / "run")
    assert code == 2 and "--point 200 50 is off the camera's 160x120 image" in one_line(err)
