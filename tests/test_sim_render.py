"""The simulated camera's renderer (sim_fallback.render): exact geometry, textured meshes, the lamp's shadows,
finishes, exposure and noise, the cached static scene, and the depth models' artefacts in rendered scenes."""

import cv2
import numpy as np
import pybullet as pb
import pytest

from drivers.camera.depth_noise import DepthNoise
from sim_fallback.camera import SimCamera, d415_intrinsics
from sim_fallback.camera_scenes import box, look_along_x, wall
from sim_fallback.furniture import Finish
from sim_fallback.render.renderer import RayRenderer
from sim_fallback.render.stereo import ActiveStereo
from sim_fallback.render.tiny import TinyRenderer
from sim_fallback.scenario import Scenario
from sim_fallback.world import SimWorld

K = d415_intrinsics(320, 240)
T = look_along_x(1.0)  # at (0, 0, 1) looking along +x: image right is world -y, image down is world -z


@pytest.fixture
def client():
    c = pb.connect(pb.DIRECT)
    yield c
    pb.disconnect(c)


def _rng():
    return np.random.default_rng(0)


def test_a_wall_at_a_known_distance_reads_its_exact_depth(client):
    wall(client, 1.2)
    out = RayRenderer(client, K).render(T, _rng())
    np.testing.assert_allclose(out.depth_m, 1.2, atol=2e-6)
    assert np.all(out.links[..., 0] == 0) and np.all(out.links[..., 1] == -1)


def test_spheres_cylinders_and_capsules_have_their_shape(client):
    c = client
    wall(c, 2.5)
    shapes = [pb.createVisualShape(pb.GEOM_SPHERE, radius=0.15, physicsClientId=c),
              pb.createVisualShape(pb.GEOM_CYLINDER, radius=0.08, length=0.4, physicsClientId=c),
              pb.createVisualShape(pb.GEOM_CAPSULE, radius=0.06, length=0.3, physicsClientId=c)]
    turned = pb.getQuaternionFromEuler([0.4, 0.3, 0.0])
    centres = ([1.5, 0.35, 1.0], [1.3, 0.0, 1.0], [1.6, -0.4, 0.9])
    sphere, *others = [pb.createMultiBody(0, -1, shape, position, turned, physicsClientId=c)
                       for shape, position in zip(shapes, centres, strict=True)]
    ours = RayRenderer(c, K).render(T, _rng())
    # the sphere: the ray toward its centre meets it at |c| - r, depth (along x) (|c| - r) c_x / |c|
    centre = np.array(centres[0]) - T[:3, 3]
    u, v = K.fx * -centre[1] / centre[0] + K.cx, K.fy * -centre[2] / centre[0] + K.cy
    expected = (np.linalg.norm(centre) - 0.15) * centre[0] / np.linalg.norm(centre)
    assert ours.depth_m[round(v), round(u)] == pytest.approx(expected, abs=0.003)  # facets: 15 deg
    assert ours.links[round(v), round(u), 0] == sphere
    pybullets = TinyRenderer(c, K).render(T, _rng())  # cylinders and capsules as PyBullet draws them
    for body in others:
        both = (ours.links[..., 0] == body) & (pybullets.links[..., 0] == body)
        either = (ours.links[..., 0] == body) | (pybullets.links[..., 0] == body)
        assert both.sum() > 300 and both.sum() / either.sum() > 0.9
        assert np.median(np.abs(ours.depth_m - pybullets.depth_m)[both]) < 0.002


def _textured_object(folder):
    """A PartNet-Mobility-like object: mobility.urdf, one link drawn by textured_objs/quad.obj (+ MTL) with
    images/texture.png: its quarters red (top left), green (top right), blue (bottom left), white."""
    (folder / "textured_objs").mkdir()
    (folder / "images").mkdir()
    image = np.zeros((64, 64, 3), np.uint8)  # BGR, row 0 at the top (v = 1)
    image[:32, :32], image[:32, 32:], image[32:, :32], image[32:, 32:] = (0, 0, 255), (0, 255, 0), (255, 0, 0), 255
    cv2.imwrite(str(folder / "images" / "texture.png"), image)
    (folder / "textured_objs" / "quad.mtl").write_text(
        "newmtl paint\nKd 1 1 1\nmap_Kd ../images/texture.png\n")
    # facing -x at x = 1: u runs toward -y (image right), v toward +z (image up)
    (folder / "textured_objs" / "quad.obj").write_text(
        "mtllib quad.mtl\nv 1 0.3 0.7\nv 1 -0.3 0.7\nv 1 -0.3 1.3\nv 1 0.3 1.3\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl paint\nf 1/1 2/2 3/3 4/4\n")
    (folder / "mobility.urdf").write_text(
        '<robot name="quad"><link name="base"/><link name="link_0"><visual><geometry>'
        '<mesh filename="textured_objs/quad.obj"/></geometry></visual></link>'
        '<joint name="joint_0" type="fixed"><parent link="base"/><child link="link_0"/></joint></robot>')
    return folder / "mobility.urdf"


def test_a_textured_mesh_is_drawn_with_its_texture(client, tmp_path):
    body = pb.loadURDF(str(_textured_object(tmp_path)), useFixedBase=True, physicsClientId=client)
    out = RayRenderer(client, K).render(T, _rng())
    drawn = out.links[..., 0] == body
    rows, cols = np.nonzero(drawn)
    assert drawn.sum() > 0.2 * drawn.size
    mid_r, mid_c = (rows.min() + rows.max()) // 2, (cols.min() + cols.max()) // 2
    colour = out.color.astype(int)
    quarters = {"red": (rows < mid_r - 3) & (cols < mid_c - 3), "green": (rows < mid_r - 3) & (cols > mid_c + 3),
                "blue": (rows > mid_r + 3) & (cols < mid_c - 3), "white": (rows > mid_r + 3) & (cols > mid_c + 3)}
    for name, where in quarters.items():
        r, g, b = colour[rows[where], cols[where]].mean(axis=0)
        expected = {"red": r > 3 * max(g, b), "green": g > 3 * max(r, b), "blue": b > 3 * max(r, g),
                    "white": min(r, g, b) > 0.7 * max(r, g, b) and min(r, g, b) > 60}[name]
        assert expected, (name, r, g, b)


def test_the_lamp_casts_a_shadow(client):
    floor = box(client, (3.0, 3.0, 0.005), np.array([1.0, 0.0, -0.005]), 0.0)
    block = box(client, (0.1, 0.1, 0.1), np.array([1.0, 0.0, 0.5]), 0.0)
    T_down = np.eye(4)
    T_down[:3, :3] = [[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]  # looking straight down
    T_down[:3, 3] = [1.0, 0.0, 1.8]
    renderer = RayRenderer(client, K)
    out = renderer.render(T_down, _rng())
    lamp = np.asarray(renderer.lighting(T_down).lamp.position)
    v, u = np.mgrid[0:K.height, 0:K.width]
    rays = np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones_like(u, float)], -1) @ T_down[:3, :3].T
    points = T_down[:3, 3] + out.depth_m[..., None] * rays
    on_floor = out.links[..., 0] == floor
    expected = _segment_meets_box(points[on_floor], lamp, np.array([0.9, -0.1, 0.4]), np.array([1.1, 0.1, 0.6]))
    lit = out.seen.lit[0].reshape(K.height, K.width)[on_floor]
    assert expected.sum() > 500  # the shadow is in view
    assert np.mean(lit == ~expected) > 0.995
    grey = out.color.astype(float).mean(axis=-1)[on_floor]
    assert np.median(grey[expected]) < 0.85 * np.median(grey[~expected])
    assert (out.links[..., 0] == block).any()


def _segment_meets_box(points, target, lo, hi):
    """Whether the segments from `points` (n, 3) to `target` pass through the box [lo, hi] (slab test)."""
    d = target - points
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (lo - points) / d, (hi - points) / d
    near = np.nanmax(np.minimum(t0, t1), axis=1)
    far = np.nanmin(np.maximum(t0, t1), axis=1)
    return (near <= far) & (far > 0) & (near < 1)


def test_finishes_set_colour_and_pattern(client):
    plain, wooden = (box(client, (0.02, 0.3, 0.3), np.array([1.0, y, 1.0]), 0.0) for y in (0.32, -0.32))
    finishes = {(wooden, -1): Finish("wood", (0.5, 0.25, 0.1), 0.1, 3)}
    out = RayRenderer(client, K, finishes).render(T, _rng())
    colour = out.color.astype(float)
    r, g, b = colour[out.links[..., 0] == wooden].mean(axis=0)
    assert r > g > b  # the finish's colour, not the URDF's grey

    def grain(body):  # how much the body's mean red varies from row to row beyond a smooth trend
        mask = out.links[..., 0] == body  # (the grain runs sideways: a row averages the noise, keeps the grain)
        rows = np.flatnonzero(mask.sum(axis=1) > 50)
        profile = np.array([colour[r, mask[r], 0].mean() for r in rows])
        return np.std(profile - np.polyval(np.polyfit(rows, profile, 2), rows))

    assert grain(wooden) > 3 * grain(plain)
    finishes[(plain, -1)] = Finish("metal", (0.2, 0.6, 0.2), 0.6, 1)  # read at every frame
    later = RayRenderer(client, K, finishes)
    again = later.render(T, _rng()).color.astype(float)[out.links[..., 0] == plain].mean(axis=0)
    assert again[1] > 1.5 * again[0]


def test_exposure_and_colour_noise_are_seeded(client):
    wall(client, 1.0)
    renderer = RayRenderer(client, K)
    first, second = renderer.render(T, np.random.default_rng(1)).color, renderer.render(T, np.random.default_rng(2)
                                                                                         ).color
    assert np.mean(first != second) > 0.3  # sensor noise differs frame to frame
    assert abs(first.astype(float).mean() - second.astype(float).mean()) < 1.0
    again = RayRenderer(client, K).render(T, np.random.default_rng(1)).color
    np.testing.assert_array_equal(first, again)
    assert 60 < first.mean() < 200  # auto exposure: neither black nor burnt out


@pytest.fixture(scope="module")
def world():
    with SimWorld(Scenario.make("drawer", 1), floor=True) as w:
        yield w


def test_link_image_matches_pybullet_segmentation(world):
    camera = SimCamera(world, intrinsics=K)
    links = camera.link_image()
    truth = TinyRenderer(world.client, K).render(camera.T_base_camera, _rng()).links
    assert np.mean(np.all(links == truth, axis=-1)) > 0.995
    for body in (world.robot_id, world.cabinet_id):
        assert (links[..., 0] == body).sum() > 100
    assert (links[..., 1] == world.handle_link).sum() > 20


def test_cached_frames_match_fresh_renders(world):
    """Frames after the arm and the drawer moved (drawn from the cached static scene and the moving links) equal a
    new renderer's, which draws everything as static."""
    c = world.client
    cached = RayRenderer(c, K)
    T_camera = world.scenario.T_base_camera
    cached.render(T_camera, _rng())
    try:
        for step in range(3):
            pb.resetJointState(world.robot_id, 1, -0.2 + 0.1 * step, physicsClientId=c)
            pb.resetJointState(world.cabinet_id, world.cabinet_joint, 0.04 * step, physicsClientId=c)
            a, b = cached.render(T_camera, _rng()), RayRenderer(c, K).render(T_camera, _rng())
            np.testing.assert_allclose(a.depth_m, b.depth_m, atol=1e-5)
            assert np.mean(np.all(a.links == b.links, axis=-1)) > 0.9999
            assert np.mean(a.seen.lit[0] != b.seen.lit[0]) < 0.01  # moving shadows: 2-pixel steps
            shade_a = a.seen.image("colour", cached.lighting(T_camera).shade)
            shade_b = b.seen.image("colour", cached.lighting(T_camera).shade)
            assert np.mean(np.abs(shade_a - shade_b) > 1e-4) < 0.01
        assert cached.scene.moving.sum() >= 2  # the arm's and the drawer's links left the static scene
    finally:
        pb.resetJointState(world.robot_id, 1, world.scenario.q_start[1], physicsClientId=c)
        pb.resetJointState(world.cabinet_id, world.cabinet_joint, 0.0, physicsClientId=c)


def _box_wall_bar(client):
    """A wall 1 m away, a box 0.6 m away in the middle, a 3 mm bar 0.9 m away on the right."""
    wall(client, 1.0)
    box(client, (0.05, 0.1, 0.1), np.array([0.65, 0.0, 1.0]), 0.0)
    return box(client, (0.005, 0.0015, 0.15), np.array([0.9, -0.25, 1.0]), 0.0)


def test_the_d415_model_loses_depth_where_stereo_would(client):
    bar = _box_wall_bar(client)
    intrinsics = d415_intrinsics()
    out = RayRenderer(client, intrinsics).render(T, _rng())
    depth = DepthNoise.d415().apply(out.depth_m, intrinsics.fx, _rng(), reflectance=out.reflectance)
    f_b = intrinsics.fx * 0.055
    row = intrinsics.height // 2
    assert np.all(depth[:, : int(f_b / 1.0) - 1] == 0) and np.mean(depth[:, int(f_b) + 3:] > 0) > 0.9  # band
    box_cols = np.flatnonzero(np.abs(out.depth_m[row] - 0.6) < 1e-3)
    shadow = f_b * (1 / 0.6 - 1 / 1.0)
    beside = depth[row, box_cols[0] - int(shadow) + 2: box_cols[0] - 2]
    assert len(beside) > 10 and np.all(beside == 0)  # the IR shadow left of the box
    assert np.all(depth[row, box_cols[-1] + 3: box_cols[-1] + 30] > 0)  # none to its right
    on_bar = out.links[..., 0] == bar
    assert on_bar.sum() > 50 and np.mean(depth[on_bar] > 0) < 0.1  # the thin bar's depth is lost


def _stereo(client):
    """The D415's intrinsics, the active stereo model, its left (colour-side) render and the depth it measures."""
    intrinsics = d415_intrinsics()
    stereo = ActiveStereo()
    renderer = RayRenderer(client, intrinsics)
    projector = stereo.projector(T)
    left = renderer.render(T, _rng(), (projector,))
    right = renderer.see("right", stereo.right(T), (projector,))
    return intrinsics, stereo, left, stereo.measure(left.seen, right, T, intrinsics, _rng())


def test_active_stereo_measures_a_wall_like_a_d415(client):
    wall(client, 1.0)
    intrinsics, stereo, left, depth = _stereo(client)
    h, w = depth.shape
    central = depth[h // 10: -h // 10, w // 10: -w // 10]
    assert np.mean(central > 0) > 0.97
    assert np.sqrt(np.mean((central[central > 0] - 1.0) ** 2)) < 0.02  # the datasheet: under 2 % at 2 m
    band = np.argmax((depth > 0).mean(axis=0) > 0.5)
    assert abs(band - intrinsics.fx * stereo.baseline_m / 1.0) < 3


def test_stereo_and_the_model_shadow_the_same_pixels(client):
    _box_wall_bar(client)
    intrinsics, stereo, left, measured = _stereo(client)
    model = DepthNoise(stereo_shadows=True, stereo_margin_px=1).apply(left.depth_m, intrinsics.fx, _rng())
    rows = slice(intrinsics.height // 2 - 30, intrinsics.height // 2 + 30)
    lost_stereo, lost_model = measured[rows] == 0, model[rows] == 0
    assert lost_model.sum() > 1000
    assert (lost_stereo & lost_model).sum() / (lost_stereo | lost_model).sum() > 0.7
