"""PartNet-Mobility objects: a small object in the dataset's layout, made here, loads, lists its parts, opens its
drawer and door in PyBullet, has its handles where they were built, stands in the furniture frame whichever
model axis its front faces, and is sized as real furniture or kept at its own scale."""

from dataclasses import replace

import numpy as np
import pybullet as pb
import pytest
from partnet_objects import BAR_LENGTH, BAR_THICKNESS, BODY, DRAWER_OVER_DOOR, FRONT_X, Front, write_object
from scipy.spatial.transform import Rotation

from sim_fallback.partnet import list_objects, load_partnet, usable
from sim_fallback.partnet.check import check_furniture, check_part, grip_points
from sim_fallback.partnet.loader import FITTING_GAP_M
from sim_fallback.partnet.naming import grid_positions, part_names
from sim_fallback.partnet.sizes import CATEGORY_RANGE_M, real_scale


@pytest.fixture(autouse=True)
def cache(tmp_path, monkeypatch):
    """URDF copies go to a cache of the test's own."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


def in_furniture(point_front, scale=1.0):
    """A point given in the test object's front coordinates, in the furniture frame: the footprint's centre
    (the body and fronts, handles left out) on the floor."""
    footprint = np.array([(FRONT_X - BODY[0] / 2) / 2, 0.0, -BODY[2] / 2])
    return scale * (np.asarray(point_front) - footprint)


def test_a_folder_lists_its_objects_parts_and_the_links_that_are_not_parts(tmp_path):
    write_object(tmp_path / "assets" / "101")
    write_object(tmp_path / "assets" / "7")
    entries = list_objects(tmp_path / "assets")
    assert [e.object_id for e in entries] == ["7", "101"]  # ids in numeric order
    entry = entries[1].describe()
    assert entry["category"] == "StorageFurniture" and entry["problem"] is None
    assert [(p["name"], p["kind"], p["link"], p["joint"], p["unit"], p["handle"]) for p in entry["parts"]] == [
        ("drawer", "drawer", "link_1", "joint_1", "m", "bar"), ("door", "door", "link_2", "joint_2", "deg", "bar")]
    scale = entries[1].furniture.scale
    assert entry["parts"][0]["range"] == [0.0, pytest.approx(0.6 * scale, abs=1e-3)]  # scaled with the model
    assert entry["parts"][1]["range"] == [0.0, pytest.approx(90.0)]
    assert entry["ignored"] == ["link_3 (slider button, prismatic joint): not a drawer or door"]
    assert len(usable(entries)) == 2


@pytest.mark.parametrize("front_axis", ["+z", "+x", "-x"])
def test_the_model_stands_z_up_with_its_front_on_x_whichever_axis_it_faces(tmp_path, front_axis):
    furniture = load_partnet(write_object(tmp_path / "1", front_axis), scale="native")
    assert furniture.scale == 1.0
    gap = FITTING_GAP_M  # left beside and above it in a kitchen (its door swings within the body's sides)
    np.testing.assert_allclose(furniture.size_m, [BODY[1] + 2 * gap, FRONT_X + BODY[0] / 2, BODY[2] + 0.02 + gap],
                               atol=1e-6)
    points = grip_points(furniture)  # through PyBullet: the loaded URDF at T_urdf
    for front in DRAWER_OVER_DOOR:
        np.testing.assert_allclose(points[front.kind], in_furniture(front.grip_centre()), atol=1e-6)


def test_handle_truth_is_the_bar_built_on_each_front(tmp_path):
    furniture = load_partnet(write_object(tmp_path / "1", "+x"))
    s = furniture.scale
    client = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(str(furniture.urdf), furniture.T_urdf[:3, 3].tolist(),
                           Rotation.from_matrix(furniture.T_urdf[:3, :3]).as_quat().tolist(),
                           useFixedBase=True, globalScaling=s, physicsClientId=client)
        links = {pb.getJointInfo(body, j, physicsClientId=client)[12].decode(): j
                 for j in range(pb.getNumJoints(body, physicsClientId=client))}
        for front, part in zip(DRAWER_OVER_DOOR, furniture.parts, strict=True):
            state = pb.getLinkState(body, links[part.link], computeForwardKinematics=True, physicsClientId=client)
            R = np.reshape(pb.getMatrixFromQuaternion(state[5]), (3, 3))
            h = part.handle
            np.testing.assert_allclose(R @ h.centre + state[4], in_furniture(front.grip_centre(), s), atol=1e-6)
            np.testing.assert_allclose(R @ h.normal, [1, 0, 0], atol=1e-9)
            expected_axis = [0, 1, 0] if front.kind == "drawer" else [0, 0, 1]
            np.testing.assert_allclose(np.abs(R @ h.axis), expected_axis, atol=1e-9)
            assert h.length_m == pytest.approx(BAR_LENGTH * s) and h.thickness_m == pytest.approx(BAR_THICKNESS * s)
            assert h.style == "bar"
    finally:
        pb.disconnect(client)


def test_drawer_and_door_open_in_pybullet_as_their_joints_say(tmp_path):
    furniture = load_partnet(write_object(tmp_path / "1", drawer_open=0.1))
    drawer, door = furniture.parts
    assert drawer.upper == pytest.approx(0.6 * furniture.scale)  # range re-based to start closed at 0
    assert door.upper == pytest.approx(np.pi / 2)
    checks = check_furniture(furniture)
    assert [c.problems for c in checks] == [(), ()]
    for check in checks:
        assert check.reached == pytest.approx(check.target, rel=0.02) and check.target > 0
        assert check.pose_error_m < 1e-3 and check.fingers_free
        assert check.grip_distance_m < 0  # the grip centre is inside the handle's own shape
    # closed is where the drawer was modelled 0.1 out minus that 0.1: its front flush with the body's
    assert grip_points(furniture)["drawer"][0] == pytest.approx(in_furniture(DRAWER_OVER_DOOR[0].grip_centre(),
                                                                             furniture.scale)[0])


def test_a_continuous_hinge_opens_as_far_as_a_cabinet_hinge(tmp_path):
    folder = write_object(tmp_path / "1")
    urdf = folder / "mobility.urdf"
    urdf.write_text(urdf.read_text().replace('type="revolute"', 'type="continuous"'))
    furniture = load_partnet(folder)
    assert furniture.part("door").upper == pytest.approx(np.radians(110.0))
    assert check_part(furniture, furniture.part("door")).ok


def test_the_check_fails_for_a_handle_off_its_front_or_without_room_for_the_fingers(tmp_path):
    furniture = load_partnet(write_object(tmp_path / "1"), scale="native")
    drawer = furniture.part("drawer")
    assert check_part(furniture, drawer).ok
    inside = replace(drawer.handle, centre=tuple(np.add(drawer.handle.centre, [-0.5, 0.0, 0.0])))  # in the body
    problems = " ".join(check_part(furniture, replace(drawer, handle=inside)).problems)
    assert "not on the part's front" in problems
    thin = replace(drawer.handle, thickness_m=0.0)  # the fingers' places then cut into the bar
    assert "no room for the fingers" in " ".join(check_part(furniture, replace(drawer, handle=thin)).problems)


def test_real_size_puts_every_dimension_in_its_category_range_and_scales_the_drawer(tmp_path):
    folder = write_object(tmp_path / "1")
    native, real = load_partnet(folder, scale="native"), load_partnet(folder, scale="real")
    low, high = np.array(CATEGORY_RANGE_M["StorageFurniture"]).T
    assert np.all(np.array(real.size_m) >= low) and np.all(np.array(real.size_m) <= high)
    gaps = np.array([2, 0, 1]) * FITTING_GAP_M
    np.testing.assert_allclose(np.array(real.size_m) - gaps, (np.array(native.size_m) - gaps) * real.scale)
    assert real.part("drawer").upper == pytest.approx(native.part("drawer").upper * real.scale)
    assert real.part("door").upper == native.part("door").upper
    assert real_scale(np.array(native.size_m), "Microwave") < real.scale  # the same model as a microwave: smaller


def test_scale_rule_takes_the_middle_of_what_fits_or_the_least_misfit():
    size = np.array([1.0, 1.0, 1.0])
    s = real_scale(size, "StorageFurniture")  # depth allows 0.3-0.65: the only binding range
    assert s == pytest.approx(np.sqrt(0.30 * 0.65))
    flat = real_scale(np.array([1.0, 1.0, 0.1]), "Dishwasher")  # no scale fits all three
    assert 0.55 < flat < 8.0


def test_part_names_follow_rows_and_columns_as_seen_from_the_front():
    # spans: lateral (to the viewer's right) and vertical
    stack = [(-0.3, 0.3, 0.6, 0.8), (-0.3, 0.3, 0.4, 0.6), (-0.3, 0.3, 0.2, 0.4)]
    assert part_names("drawer", grid_positions(np.array(stack))) == ["top drawer", "middle drawer", "bottom drawer"]
    pair = [(0.0, 0.4, 0.0, 1.0), (-0.4, 0.0, 0.0, 1.0)]
    positions = grid_positions(np.array(pair))
    assert part_names("door", positions) == ["right door", "left door"]
    four = [(-0.3, 0.3, z, z + 0.1) for z in (0.9, 0.7, 0.5, 0.3)]
    assert part_names("drawer", grid_positions(np.array(four))) == ["top drawer", "second drawer", "third drawer",
                                                                    "bottom drawer"]


def test_parts_are_named_and_ordered_top_to_bottom_then_left_to_right(tmp_path):
    fronts = (Front("door", (0.0, 0.48), (-0.58, 0.23)), Front("drawer", (-0.48, 0.48), (0.25, 0.40)),
              Front("door", (-0.48, 0.0), (-0.58, 0.23)), Front("drawer", (-0.48, 0.48), (0.41, 0.58), handle=None))
    furniture = load_partnet(write_object(tmp_path / "1", fronts=fronts))
    assert [(p.name, p.link) for p in furniture.parts] == [
        ("top drawer", "link_4"), ("bottom drawer", "link_2"), ("left door", "link_3"), ("right door", "link_1")]
    assert furniture.part("top drawer").handle is None  # the model does not say where its handle is
    assert furniture.part("link_1").name == "right door"
    assert all(c.ok for c in check_furniture(furniture))
