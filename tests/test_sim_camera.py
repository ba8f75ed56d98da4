"""The simulated D415: geometry of depth against ray casting, segmentation, noise, timestamps."""

import numpy as np
import open3d as o3d
import pybullet as pb
import pytest

from drivers.camera.base import Camera, SegLabel
from drivers.camera.depth_noise import DepthNoise
from sim_fallback.camera import SimCamera, d415_intrinsics
from sim_fallback.scenario import Scenario
from sim_fallback.world import SimWorld


@pytest.fixture(scope="module")
def world():
    with SimWorld(Scenario.make("drawer", 1)) as w:
        yield w


def _rays(frame, dv=0.0, du=0.0):
    """Unit-depth view rays (H, W, 3) of every pixel centre in the base frame, and the camera position."""
    K, T = frame.intrinsics, frame.T_base_camera
    v, u = np.mgrid[0:K.height, 0:K.width].astype(float)
    rays = np.stack([(u + du - K.cx) / K.fx, (v + dv - K.cy) / K.fy, np.ones_like(u)], -1)
    return rays @ T[:3, :3].T, T[:3, 3]


def _points(frame):
    rays, eye = _rays(frame)
    return eye + frame.depth_m[..., None] * rays


def _face_depth(world, frame, normal_cab, offset_m, dv=0.0, du=0.0):
    """Depth along the optical axis of the cabinet body's outer face {x : n.x = offset} (cabinet frame) and
    the pixels whose ray meets it at least 3 cm inside its edges."""
    spec, Tc = world.scenario.cabinet, world.scenario.T_base_cabinet
    rays, eye = _rays(frame, dv, du)
    n = Tc[:3, :3] @ normal_cab
    depth = ((Tc[:3, :3] @ (normal_cab * offset_m) + Tc[:3, 3] - eye) @ n) / (rays @ n)
    local = (eye + depth[..., None] * rays - Tc[:3, 3]) @ Tc[:3, :3]
    half = np.array([spec.depth_m, spec.width_m, spec.height_m]) / 2 - 0.03
    centred = local - [0, 0, spec.height_m / 2]
    inside = np.all((np.abs(centred) < half) | (np.abs(normal_cab) > 0), axis=-1)
    return depth, inside & (frame.segmentation == SegLabel.OBJECT)


@pytest.mark.parametrize("resolution", [(320, 240), (640, 480)])
def test_depth_of_known_surfaces_matches_geometry(world, resolution):
    frame = SimCamera(world, intrinsics=d415_intrinsics(*resolution), noise=DepthNoise.none(), labels=True,
                      posed=True).read()
    spec = world.scenario.cabinet
    side = np.sign(world.scenario.camera.azimuth_rad)  # the camera sees this side face and the top
    for normal, offset in (([0, 0, 1.0], spec.height_m), ([0, side, 0], spec.width_m / 2)):
        expected, pixels = _face_depth(world, frame, np.array(normal), offset)
        assert pixels.sum() > 200
        error = np.abs(frame.depth_m - expected)[pixels]
        assert np.median(error) < 1e-4 and np.quantile(error, 0.99) < 1e-3
        # half a pixel off would be visible: the geometry pins the pixel-centre convention
        shifted, _ = _face_depth(world, frame, np.array(normal), offset, dv=0.5, du=0.5)
        assert np.median(np.abs(frame.depth_m - shifted)[pixels]) > 5e-4


def _aabb_contains(aabbs, points, margin_m=0.005):
    inside = np.zeros(len(points), bool)
    for lo, hi in aabbs:
        inside |= np.all((points >= np.subtract(lo, margin_m)) & (points <= np.add(hi, margin_m)), axis=1)
    return inside


def test_segmentation_labels_are_where_the_bodies_are(world):
    frame = SimCamera(world, intrinsics=d415_intrinsics(320, 240), noise=DepthNoise.none(), labels=True,
                      posed=True).read()
    points, labels, c = _points(frame), frame.segmentation, world.client
    counts = np.bincount(labels.ravel(), minlength=4)
    assert np.all(counts > 20), counts
    n_robot_links = pb.getNumJoints(world.robot_id, physicsClientId=c)
    links = {
        SegLabel.OBJECT: [(world.cabinet_id, j) for j in (-1, 0, 1)],
        SegLabel.HANDLE: [(world.cabinet_id, world.handle_link)],
        SegLabel.ROBOT: [(world.robot_id, j) for j in range(-1, n_robot_links)],
    }
    for label, parts in links.items():
        boxes = [pb.getAABB(body, link, physicsClientId=c) for body, link in parts]
        assert np.mean(_aabb_contains(boxes, points[labels == label])) > 0.99, label
    # background: empty space (depth 0) or the pedestal below the cabinet
    background = labels == SegLabel.BACKGROUND
    assert np.mean(frame.depth_m[background] == 0) > 0.5
    below = points[background & (frame.depth_m > 0), 2] < world.scenario.pedestal_height_m + 1e-3
    assert np.all(below)


def test_noise_is_switchable_and_seeded(world):
    clean_camera = SimCamera(world, intrinsics=d415_intrinsics(320, 240), noise=DepthNoise.none())
    _, clean, _ = clean_camera.render()
    np.testing.assert_array_equal(clean_camera.read().depth_m, clean)

    noisy = SimCamera(world, intrinsics=d415_intrinsics(320, 240), seed=3).read().depth_m
    again = SimCamera(world, intrinsics=d415_intrinsics(320, 240), seed=3).read().depth_m
    np.testing.assert_array_equal(noisy, again)
    both = (clean > 0) & (noisy > 0)
    diff = np.abs(noisy - clean)[both]
    assert 2e-4 < np.median(diff) < 1e-2  # millimetres at about 1 m
    holes = np.mean(noisy[clean > 0] == 0)
    assert 0.005 < holes < 0.2


def test_timestamps_follow_the_simulated_clock_and_frames_can_drop():
    with SimWorld(Scenario.make("door", 2)) as world:
        camera = SimCamera(world, intrinsics=d415_intrinsics(160, 120), fps=10.0, posed=True)
        assert isinstance(camera, Camera)
        first, second = camera.read(), camera.read()
        assert (first.index, first.t) == (0, 0.0)
        assert second.index == 1 and second.t == pytest.approx(0.1) and world.time == pytest.approx(0.1)
        world.clock.step(84)  # the caller is 0.35 s late: the frames it missed are skipped
        late = camera.read()
        assert late.index == 4 and late.t == pytest.approx(0.45)
        np.testing.assert_allclose(late.T_base_camera, world.scenario.T_base_camera)

        dropping = SimCamera(world, intrinsics=d415_intrinsics(160, 120), fps=10.0, drop_rate=0.5, seed=1)
        frames = [dropping.read() for _ in range(12)]
        indices = np.array([f.index for f in frames])
        assert np.all(np.diff(indices) >= 1) and np.any(np.diff(indices) > 1)
        assert frames[0].index == 4  # started mid-slot: the current one, at the current time
        np.testing.assert_allclose([f.t for f in frames[1:]], indices[1:] / 10.0, atol=1e-9)


def test_intrinsics_are_d415_like_and_the_camera_holds_no_ground_truth(world):
    hd = d415_intrinsics(1280, 720)
    vfov = np.degrees(2 * np.arctan(hd.height / 2 / hd.fy))
    hfov = np.degrees(2 * np.arctan(hd.width / 2 / hd.fx))
    assert hfov == pytest.approx(65.0) and 38 < vfov < 42
    camera = SimCamera(world, intrinsics=d415_intrinsics(160, 120))
    assert not any(isinstance(value, SimWorld) for value in vars(camera).values())
    assert not hasattr(camera, "truth")
    with pytest.raises(ValueError, match="drop_rate"):
        SimCamera(world, drop_rate=1.0)


def test_optional_floor_is_background_with_depth():
    with SimWorld(Scenario.make("drawer", 1), floor=True) as world:
        frame = SimCamera(world, intrinsics=d415_intrinsics(160, 120), noise=DepthNoise.none(), labels=True,
                          posed=True).read()
    background = frame.segmentation == SegLabel.BACKGROUND
    assert np.mean(frame.depth_m[background] > 0) > 0.5
    points = _points(frame)[background]
    assert np.median(np.abs(points[:, 2])) < 0.01  # mostly the floor at z = 0


def test_robot_is_drawn_close_to_its_collision_meshes(world):
    """The arm is drawn with decimated collision meshes: a quarter of the triangles, surfaces within mm."""
    c, robot = world.client, world.robot_id
    o3d.utility.random.seed(0)
    for link in range(-1, pb.getNumJoints(robot, physicsClientId=c)):
        drawn = [v[4].decode() for v in pb.getVisualShapeData(robot, physicsClientId=c) if v[1] == link]
        built = [s[4].decode() for s in pb.getCollisionShapeData(robot, link, physicsClientId=c)
                 if s[2] == pb.GEOM_MESH]
        if not built:
            continue
        low, full = (o3d.io.read_triangle_mesh(paths[0]) for paths in (drawn, built))
        full.remove_duplicated_vertices()
        assert len(low.triangles) <= 0.3 * len(full.triangles) or len(low.triangles) == len(full.triangles) < 100
        for a, b in ((low, full), (full, low)):  # both ways: nothing added, nothing lost
            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(b))
            points = np.asarray(a.sample_points_uniformly(2000).points, np.float32)
            distance = scene.compute_distance(points).numpy()
            assert np.median(distance) < 0.0015 and np.quantile(distance, 0.99) < 0.008, drawn[0]


def test_frames_carry_what_a_real_camera_gives_unless_the_truth_is_asked_for(world):
    plain = SimCamera(world, intrinsics=d415_intrinsics(160, 120)).read()
    assert plain.segmentation is None and plain.T_base_camera is None and plain.mask is None
    assert plain.color.shape == (120, 160, 3) and plain.depth_m.shape == (120, 160)
    truth = SimCamera(world, intrinsics=d415_intrinsics(160, 120), labels=True, posed=True).read()
    assert truth.segmentation is not None
    np.testing.assert_allclose(truth.T_base_camera, world.scenario.T_base_camera)
