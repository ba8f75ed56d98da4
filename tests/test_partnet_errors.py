"""Bad PartNet-Mobility input: one line each, naming the thing, the cause and the fix; nothing else is lost."""

import numpy as np
import pytest
from partnet_objects import Front, write_object

from sim_fallback.partnet import PartNetError, find_object, list_objects, load_partnet
from sim_fallback.partnet.check import parts_within_reach


@pytest.fixture(autouse=True)
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


def one_line(exc_info) -> str:
    message = str(exc_info.value)
    assert "\n" not in message and "fix:" in message
    return message


def test_a_folder_not_in_the_layout(tmp_path):
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "chair.obj").write_text("v 0 0 0\n")
    with pytest.raises(PartNetError) as exc:
        list_objects(tmp_path)
    assert "not in the PartNet-Mobility layout" in one_line(exc) and str(tmp_path) in str(exc.value)
    with pytest.raises(PartNetError) as exc:
        list_objects(tmp_path / "nowhere")
    assert "no such folder" in one_line(exc)


def test_an_object_whose_meshes_are_missing(tmp_path):
    folder = write_object(tmp_path / "12")
    (folder / "textured_objs" / "original-3.obj").unlink()
    with pytest.raises(PartNetError) as exc:
        load_partnet(folder)
    message = one_line(exc)
    assert "partnet 12" in message and "1 of its" in message and "textured_objs/original-3.obj" in message


@pytest.mark.parametrize("text", ["<robot name='x'><link name='base'>", "not xml at all",
                                  "<robot><link name='a'/><joint name='j' type='fixed'><parent link='a'/>"
                                  "<child link='b'/></joint></robot>"])
def test_a_mobility_urdf_that_does_not_parse_or_is_not_one_tree(tmp_path, text):
    folder = write_object(tmp_path / "12")
    (folder / "mobility.urdf").write_text(text)
    with pytest.raises(PartNetError) as exc:
        load_partnet(folder)
    assert "partnet 12: mobility.urdf" in one_line(exc)


def test_a_part_the_object_does_not_have_lists_the_parts_it_has(tmp_path):
    folder = write_object(tmp_path / "12")
    assert load_partnet(folder, part="door").part("door").kind == "door"
    with pytest.raises(PartNetError) as exc:
        load_partnet(folder, part="top drawer")
    assert "has no part 'top drawer': it has drawer (link_1), door (link_2)" in one_line(exc)


def test_an_object_id_not_in_the_folder_lists_the_ids(tmp_path):
    write_object(tmp_path / "assets" / "12")
    write_object(tmp_path / "assets" / "40")
    assert find_object(tmp_path / "assets", "40").name == "40"
    with pytest.raises(PartNetError) as exc:
        find_object(tmp_path / "assets", "45213")
    assert "object 45213 is not in" in one_line(exc) and "it has 12, 40" in str(exc.value)


def test_an_object_with_no_drawer_or_door_is_listed_with_its_reason_and_the_others_still_load(tmp_path):
    write_object(tmp_path / "assets" / "12")
    lid = write_object(tmp_path / "assets" / "13", fronts=(Front("drawer", (-0.48, 0.48), (0.25, 0.58),
                                                                 label="lid"),))
    entries = {e.object_id: e for e in list_objects(tmp_path / "assets")}
    assert entries["12"].furniture is not None and entries["12"].problem is None
    assert entries["13"].furniture is None
    assert "partnet 13: no drawer or door part (semantics.txt: link_0 heavy furniture_body; link_1 slider lid" in (
        entries["13"].problem)
    assert "link_1 (slider lid, prismatic joint): not a drawer or door" in entries["13"].ignored
    with pytest.raises(PartNetError) as exc:
        load_partnet(lid)
    one_line(exc)


def test_no_part_within_the_arms_reach(tmp_path):
    furniture = load_partnet(write_object(tmp_path / "12"))
    near, far = np.diag([-1.0, -1.0, 1.0, 1.0]), np.diag([-1.0, -1.0, 1.0, 1.0])  # facing the robot
    near[0, 3], far[0, 3] = 0.7, 3.0
    assert [p.name for p in parts_within_reach(furniture, near, 0.85)] == ["drawer", "door"]
    assert [p.name for p in parts_within_reach(furniture, near, 0.85, kind="door")] == ["door"]
    with pytest.raises(PartNetError) as exc:
        doors_only = (Front("door", (-0.48, 0.48), (-0.58, 0.58)),)
        parts_within_reach(load_partnet(write_object(tmp_path / "13", fronts=doors_only)), near, 0.85, kind="drawer")
    assert "partnet 13: no drawer part (it has door)" in one_line(exc)
    with pytest.raises(PartNetError) as exc:
        parts_within_reach(furniture, far, 0.85, kind="drawer")
    assert "partnet 12: no drawer within the arm's reach (0.85 m of its base): the nearest, drawer, is 2.8" in (
        one_line(exc))


def test_an_unknown_scale_rule(tmp_path):
    with pytest.raises(PartNetError) as exc:
        load_partnet(write_object(tmp_path / "12"), scale="huge")
    assert "scale 'huge'" in one_line(exc)


def test_an_object_whose_textures_are_missing(tmp_path):
    folder = write_object(tmp_path / "12")
    (folder / "images" / "texture_0.png").unlink()
    with pytest.raises(PartNetError) as exc:
        load_partnet(folder)
    assert "partnet 12: 1 texture(s) its meshes name are missing (images/texture_0.png)" in one_line(exc)
