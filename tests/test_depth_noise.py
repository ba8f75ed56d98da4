"""The D415-like depth-noise model: axial noise, quantisation, holes, range, flying pixels, dropout."""

import numpy as np
import pytest
from scipy import stats

from drivers.camera.depth_noise import DepthNoise

FX = 615.0


def wall(depth_m: float, shape=(200, 200)) -> np.ndarray:
    return np.full(shape, depth_m, np.float32)


def step(near_m=0.6, far_m=1.0, shape=(60, 80)) -> np.ndarray:
    """Left half at near_m, right half at far_m: one vertical depth edge between columns 39 and 40."""
    depth = np.full(shape, far_m, np.float32)
    depth[:, : shape[1] // 2] = near_m
    return depth


@pytest.mark.parametrize("z", [0.5, 1.0, 2.0])
def test_axial_std_on_a_flat_wall_matches_the_stereo_formula(z):
    noise = DepthNoise(subpixel=0.08)
    out = noise.apply(wall(z), FX, np.random.default_rng(0)).astype(np.float64)
    expected = z**2 * 0.08 / (FX * 0.055)
    assert np.all(out > 0)
    assert out.std() == pytest.approx(expected, rel=0.10)
    assert abs(out.mean() - z) < 5 * expected / np.sqrt(out.size)
    assert noise.sigma_m(z, FX) == pytest.approx(expected)


def test_noise_grows_with_distance_squared():
    noise = DepthNoise(subpixel=0.08)
    stds = [noise.apply(wall(z), FX, np.random.default_rng(1)).std() for z in (0.5, 1.0, 1.5)]
    assert stds[1] / stds[0] == pytest.approx(4.0, rel=0.10)
    assert stds[2] / stds[0] == pytest.approx(9.0, rel=0.10)


def test_noise_shrinks_with_focal_length():
    noise = DepthNoise(subpixel=0.08)
    rng = np.random.default_rng(2)
    assert noise.apply(wall(1.0), 2 * FX, rng).std() == pytest.approx(
        noise.apply(wall(1.0), FX, rng).std() / 2, rel=0.10
    )


def test_d415_quantises_to_the_depth_unit():
    out = DepthNoise.d415().apply(wall(0.8), FX, np.random.default_rng(3)).astype(np.float64)
    valid = out[out > 0]
    assert np.allclose(valid / 0.001, np.round(valid / 0.001), atol=1e-3)
    assert len(np.unique(valid)) > 1  # noise survives quantisation at 0.8 m (sigma ~1.5 mm)


def test_axial_noise_is_gaussian_and_independent_between_pixels():
    noise = DepthNoise(subpixel=0.08)
    out = noise.apply(wall(1.0, shape=(480, 640)), FX, np.random.default_rng(14)).astype(np.float64)
    r = (out - 1.0) / noise.sigma_m(1.0, FX)
    assert stats.kstest(r.ravel(), "norm").pvalue > 0.01
    assert np.mean(np.abs(r) > 3) == pytest.approx(0.0027, abs=0.0005)
    spectrum = np.fft.rfft(r.ravel() - r.mean(), 2 * r.size)  # zero-padded: no wrap-around
    autocorr = np.fft.irfft(np.abs(spectrum) ** 2)[: r.size // 2] / np.sum((r - r.mean()) ** 2)
    assert np.max(np.abs(autocorr[1:])) < 0.02  # white: no pixel's noise repeats or predicts another's


def test_d415_gives_the_float32_nearest_each_millimetre():
    out = DepthNoise.d415().apply(wall(0.8), FX, np.random.default_rng(15))
    valid = out[out > 0]
    assert np.array_equal(valid, (np.round(valid.astype(np.float64) / 0.001) * 0.001).astype(np.float32))


@pytest.mark.parametrize("rate", [0.02, 0.1])
def test_hole_rate(rate):
    out = DepthNoise(hole_rate=rate).apply(wall(1.0), FX, np.random.default_rng(4))
    assert np.mean(out == 0) == pytest.approx(rate, abs=0.005)
    assert np.all(out[out > 0] == np.float32(1.0))
    for half in (out[:100], out[100:], out[:, :100], out[:, 100:]):  # spread over the image
        assert np.mean(half == 0) == pytest.approx(rate, abs=0.01)


def test_min_and_max_range_give_zero():
    noise = DepthNoise.d415()
    rng = np.random.default_rng(5)
    assert np.all(noise.apply(wall(0.25), FX, rng) == 0)
    assert np.all(noise.apply(wall(12.0), FX, rng) == 0)
    right_of_band = noise.apply(wall(0.4, shape=(200, 400)), FX, rng)[:, 100:]  # the band: f B / z = 85 px
    assert np.mean(right_of_band > 0) > 0.95
    assert DepthNoise.d415().min_range_m == 0.3


def test_flying_pixels_only_at_edges_and_between_the_sides():
    depth = step()
    out = DepthNoise(flying_pixel_rate=1.0).apply(depth, FX, np.random.default_rng(6))
    changed = out != depth
    assert np.all(changed[:, [39, 40]].mean(axis=0) > 0.95)  # u == 0 exactly has probability 0
    assert not changed[:, :39].any() and not changed[:, 41:].any()
    assert np.all((out[changed] > 0.6) & (out[changed] < 1.0))


def test_flying_pixel_rate_and_small_steps():
    out = DepthNoise(flying_pixel_rate=0.5).apply(step(), FX, np.random.default_rng(7))
    assert np.mean(out[:, [39, 40]] != step()[:, [39, 40]]) == pytest.approx(0.5, abs=0.12)
    smooth = step(near_m=0.99, far_m=1.0)  # a 1 cm step is below the 2 cm edge threshold
    out = DepthNoise(flying_pixel_rate=1.0).apply(smooth, FX, np.random.default_rng(8))
    assert np.array_equal(out, smooth)


def blocks(shape=(480, 640), seed=0) -> np.ndarray:
    """Random boxes of random depth (0.5-1.5 m) over a wall, with missing-depth boxes, and two bands of
    2-row stripes, one row out of phase, so that some column has a depth jump between any two rows."""
    rng = np.random.default_rng(seed)
    depth = np.full(shape, 1.6, np.float32)
    for _ in range(60):
        (v0, v1), (u0, u1) = np.sort(rng.integers(0, shape[0], 2)), np.sort(rng.integers(0, shape[1], 2))
        depth[v0:v1, u0:u1] = 0.0 if rng.random() < 0.2 else rng.uniform(0.5, 1.5)
    stripes = np.repeat(rng.uniform(0.5, 1.5, shape[0] // 2 + 1), 2)
    depth[:, :40], depth[:, 40:80] = stripes[: shape[0], None], stripes[1 : shape[0] + 1, None]
    return depth


def test_flying_pixels_on_a_large_image_match_a_brute_force_reference():
    depth = blocks()
    padded = np.pad(depth.astype(np.float64), 1, mode="edge")
    nbs = np.stack([padded[:-2, 1:-1], padded[2:, 1:-1], padded[1:-1, :-2], padded[1:-1, 2:]])
    jumps = np.where(nbs > 0, np.abs(nbs - depth), 0.0)
    edge = (depth > 0) & (jumps.max(axis=0) > 0.02)
    other = np.take_along_axis(nbs, jumps.argmax(axis=0)[None], axis=0)[0]
    out = DepthNoise(flying_pixel_rate=1.0).apply(depth, FX, np.random.default_rng(16))
    changed = out != depth
    assert edge.sum() > 5000 and np.array_equal(changed, edge)
    lo, hi = np.minimum(depth, other)[changed], np.maximum(depth, other)[changed]
    assert np.all((out[changed] > lo) & (out[changed] < hi))


def test_no_flying_pixels_next_to_missing_depth():
    depth = step(near_m=0.0, far_m=1.0)
    out = DepthNoise(flying_pixel_rate=1.0).apply(depth, FX, np.random.default_rng(9))
    assert np.array_equal(out, depth)


def tilted_plane(tilt_deg: float, shape=(100, 100)) -> np.ndarray:
    """Depth of a plane through (0, 0, 1 m) turned `tilt_deg` about the camera's y axis (0.3-3 m kept)."""
    h, w = shape
    x = (np.arange(w) - (w - 1) / 2) / FX
    c, s = np.cos(np.radians(tilt_deg)), np.sin(np.radians(tilt_deg))
    with np.errstate(divide="ignore"):
        row = c / (c + s * x)
    depth = np.broadcast_to(row[None, :], (h, w))
    return np.where((depth > 0.3) & (depth < 3.0), depth, 0.0).astype(np.float32)


def test_grazing_surfaces_drop_out():
    noise = DepthNoise(max_incidence_deg=80.0)
    steep = tilted_plane(87.0)  # incidence 82-88 deg over the image
    out = noise.apply(steep, FX, np.random.default_rng(10))
    assert (steep > 0).sum() > 1000
    assert np.mean(out[steep > 0] == 0) > 0.95
    moderate = tilted_plane(60.0)  # incidence below 66 deg everywhere
    assert np.array_equal(noise.apply(moderate, FX, np.random.default_rng(10)), moderate)
    edge = step(near_m=0.6, far_m=1.5)  # a depth jump is not a grazing surface
    assert np.array_equal(noise.apply(edge, FX, np.random.default_rng(10)), edge)


def oblique_plane(tilt_deg: float, shape=(480, 640)) -> tuple[np.ndarray, np.ndarray]:
    """Depth of a plane through (0, 0, 1 m) turned `tilt_deg` about the image diagonal (0.3-3 m kept),
    and the angle (deg) between each pixel's view ray and the plane normal."""
    h, w = shape
    x = ((np.arange(w) - (w - 1) / 2) / FX)[None, :]
    y = ((np.arange(h) - (h - 1) / 2) / FX)[:, None]
    s, c = np.sin(np.radians(tilt_deg)) / np.sqrt(2), np.cos(np.radians(tilt_deg))
    along = s * x + s * y - c  # normal (s, s, -c) . (x, y, 1)
    with np.errstate(divide="ignore"):
        depth = -c / along
    incidence = np.degrees(np.arccos(np.abs(along) / np.sqrt(x * x + y * y + 1)))
    return np.where((depth > 0.3) & (depth < 3.0), depth, 0.0).astype(np.float32), incidence


def test_grazing_dropout_follows_the_incidence_angle_over_a_large_image():
    depth, incidence = oblique_plane(70.0)  # 37-84 deg over the valid part
    dropped = DepthNoise(max_incidence_deg=80.0).apply(depth, FX, np.random.default_rng(17)) == 0
    valid = depth > 0
    assert valid.mean() > 0.7 and (valid & (incidence > 80.25)).sum() > 10000
    assert np.all(dropped[valid & (incidence > 80.25)])
    assert not dropped[valid & (incidence < 79.75)].any()


def test_none_is_identity_and_apply_is_pure():
    depth = step()
    depth[0, 0] = np.nan
    depth[1, 1] = -1.0
    before = depth.copy()
    out = DepthNoise.none().apply(depth, FX, np.random.default_rng(11))
    assert out.dtype == np.float32
    assert out[0, 0] == 0 and out[1, 1] == 0
    assert np.array_equal(out[2:], before[2:])
    assert np.array_equal(depth, before, equal_nan=True)


def test_absurd_depth_reads_zero_and_float64_input_is_untouched():
    depth = np.array([[np.nan, np.inf, -np.inf, -1.0, 0.0, 1e30, 1.0, 0.8]] * 3)
    before = depth.copy()
    for noise in (DepthNoise.d415(), DepthNoise(subpixel=0.5, flying_pixel_rate=1.0, max_incidence_deg=60.0)):
        out = noise.apply(depth, FX, np.random.default_rng(18))
        assert out.dtype == np.float32 and np.all(np.isfinite(out))
        assert np.all(out[:, :6] == 0)
    assert np.array_equal(depth, before, equal_nan=True)


@pytest.mark.parametrize("shape", [(0, 5), (5, 0), (1, 1), (1, 7), (7, 1)])
def test_tiny_images(shape):
    out = DepthNoise.d415().apply(np.full(shape, 0.8), FX, np.random.default_rng(19))
    assert out.shape == shape and out.dtype == np.float32
    assert np.all(np.abs(out[out > 0] - 0.8) < 0.01)


def test_seeded_and_deterministic():
    depth = step()
    a = DepthNoise.d415().apply(depth, FX, np.random.default_rng(12))
    b = DepthNoise.d415().apply(depth, FX, np.random.default_rng(12))
    c = DepthNoise.d415().apply(depth, FX, np.random.default_rng(13))
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_invalid_focal_length_raises():
    with pytest.raises(ValueError, match="fx"):
        DepthNoise.d415().apply(wall(1.0), 0.0, np.random.default_rng(0))


# The stereo artefacts. Left camera the reference, the right one B = 0.055 m to its right: a pixel u at depth z
# lands at u - f B / z in the right image.
STEREO = DepthNoise(stereo_shadows=True)


@pytest.mark.parametrize("z", [0.5, 1.0, 2.0])
def test_the_left_band_is_f_b_over_z_wide(z):
    out = STEREO.apply(wall(z, shape=(40, 300)), FX, np.random.default_rng(0))
    band = FX * 0.055 / z
    columns = np.arange(300)
    assert np.all(out[:, columns < band - 0.5] == 0)
    assert np.all(out[:, columns > band + 0.5] > 0)
    wider = DepthNoise(stereo_shadows=True, stereo_margin_px=2).apply(wall(z, shape=(40, 300)), FX,
                                                                      np.random.default_rng(0))
    assert (wider == 0).sum() == (out == 0).sum() + 2 * 40


def near_box(near_m=0.6, far_m=1.0, shape=(60, 300), cols=(150, 220), rows=(20, 40)) -> np.ndarray:
    depth = np.full(shape, far_m, np.float32)
    depth[rows[0]:rows[1], cols[0]:cols[1]] = near_m
    return depth


def test_a_nearer_surface_shadows_the_wall_to_its_left_only():
    depth = near_box()
    out = STEREO.apply(depth, FX, np.random.default_rng(0))
    shadow = FX * 0.055 * (1 / 0.6 - 1 / 1.0)  # 22.5 px the right camera cannot see beside the box
    row = out[30]
    left = np.arange(150 - 40, 150)
    assert np.all(row[left[left >= 150 - shadow + 0.5]] == 0)
    assert np.all(row[left[left < 150 - shadow - 0.5]] > 0)
    assert np.all(row[150:230] > 0)  # the box, and the wall to its right, are seen by both cameras
    assert np.all(out[5, 60:] > 0) and np.all(out[50, 60:] > 0)  # rows above and below the box: no shadow


def test_edges_widen_by_the_window():
    depth = near_box()
    out = DepthNoise(edge_widening_px=1).apply(depth, FX, np.random.default_rng(0))
    assert np.all(out[20:40, 220] == np.float32(0.6)) and np.all(out[20:40, 221] == np.float32(1.0))
    assert np.all(out[19, 150:220] == np.float32(0.6)) and np.all(out[18, 150:220] == np.float32(1.0))
    assert np.array_equal(DepthNoise().apply(depth, FX, np.random.default_rng(0)), depth)


@pytest.mark.parametrize("vertical", [False, True])
def test_thin_bars_lose_their_depth_wider_ones_keep_it(vertical):
    depth = np.full((80, 120), 1.0, np.float32)
    thin, wide = np.zeros(depth.shape, bool), np.zeros(depth.shape, bool)
    thin[10:70, 20:22] = True  # a bar 2 px wide standing 5 cm out of the wall
    wide[10:70, 60:72] = True  # and one 12 px wide
    depth, thin, wide = (np.ascontiguousarray(a.T) if vertical else a for a in (depth, thin, wide))
    depth[thin | wide] = 0.95
    out = DepthNoise(thin_px=3).apply(depth, FX, np.random.default_rng(0))
    assert np.all(out[thin] == 0) and np.all(out[wide] > 0) and np.all(out[~thin] > 0)


def test_dark_surfaces_far_away_lose_depth_bright_ones_keep_it():
    noise = DepthNoise(min_return=0.014)
    rng = np.random.default_rng(0)
    for z, reflectance, fill in ((1.0, 0.5, 1.0), (2.0, 0.5, 1.0), (0.5, 0.02, 1.0), (2.0, 0.02, 0.0),
                                 (2.0, 0.056, 0.5)):
        out = noise.apply(wall(z), FX, rng, reflectance=np.full((200, 200), reflectance, np.float32))
        assert np.mean(out > 0) == pytest.approx(fill, abs=0.2 if fill == 0.5 else 0.01), (z, reflectance)
    patchy = noise.apply(wall(2.0), FX, rng, reflectance=np.full((200, 200), 0.056, np.float32)) > 0
    assert 0.05 < np.mean(patchy[:, 1:] != patchy[:, :-1]) < 0.3  # patches, not salt and pepper
    assert np.all(noise.apply(wall(2.0), FX, rng) > 0)  # without the infrared return: nothing to go by


def test_dark_surfaces_beside_bright_ones_lose_depth():
    noise = DepthNoise(min_relative_return=0.07)
    reflectance = np.full((200, 200), 0.02, np.float32)
    rng = np.random.default_rng(1)
    alone = noise.apply(wall(1.0), FX, rng, reflectance=reflectance)
    assert np.all(alone > 0)  # the infrared exposure is set for it
    reflectance[:, 100:] = 0.8  # the image's mean return: 0.41, 7 % of it 0.029
    beside = noise.apply(wall(1.0), FX, rng, reflectance=reflectance)
    assert np.mean(beside[:, :100] > 0) < 0.3 and np.all(beside[:, 100:] > 0)
    reflectance[:, 100:] = 2.0
    assert np.mean(noise.apply(wall(1.0), FX, rng, reflectance=reflectance)[:, :100] > 0) < 0.01


def test_correlated_noise_keeps_its_sigma():
    noise = DepthNoise(subpixel=0.085, correlation_px=5)
    out = noise.apply(wall(1.0, shape=(480, 640)), FX, np.random.default_rng(3)).astype(np.float64)
    r = (out - 1.0) / noise.sigma_m(1.0, FX)
    assert r.std() == pytest.approx(1.0, rel=0.1)
    lag = [np.mean(r[:, k:] * r[:, :r.shape[1] - k]) for k in (1, 2, 5)]
    assert lag[0] == pytest.approx(0.8, abs=0.1) and lag[1] == pytest.approx(0.6, abs=0.1) and abs(lag[2]) < 0.1
