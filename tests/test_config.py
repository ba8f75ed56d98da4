"""Configuration: defaults, TOML files, CLI overrides and one clear message for each kind of bad input."""

import pytest

from deploy.config import Config, load_config
from deploy.errors import ConfigError


def test_defaults_without_file():
    cfg = load_config()
    assert cfg == Config()
    assert cfg.filter.resolve().radius_m == pytest.approx(0.05)
    assert cfg.filter.resolve().eps == 100


def test_toml_file_and_overrides(tmp_path):
    path = tmp_path / "robot.toml"
    path.write_text('[filter]\nprofile = "sparse"\n[estimator]\nname = "paper-obb"\nwindow = 8\n')
    cfg = load_config(path, {"filter.eps": 3, "estimator.joint": None})
    profile = cfg.filter.resolve()
    assert profile.radius_m == pytest.approx(0.013)  # the paper's 1.3, read as centimetres
    assert profile.eps == 3
    assert cfg.estimator.name == "paper-obb" and cfg.estimator.window == 8 and cfg.estimator.joint == "auto"


def test_radius_is_in_metres_whatever_the_profile(tmp_path):
    for profile in ("sim", "sparse"):
        cfg = load_config(None, {"filter.profile": profile, "filter.radius_m": 0.02})
        assert cfg.filter.resolve().radius_m == pytest.approx(0.02)  # 2 cm in simulation and on a D415 alike
    assert load_config(None, {"filter.profile": "sparse"}).filter.resolve().radius_m == pytest.approx(0.013)
    assert str(load_config(None, {"filter.profile": "sparse"}).filter.resolve()) == "radius 0.013 m (1.3 cm), eps 1"


@pytest.mark.parametrize(("text", "fix"), [
    ('[filter]\nradius = 0.02\n', "radius_m = 0.013 for 1.3 cm"),
    ('[filter]\nprofile = "sparse"\nradius = 1.5\nunit = "cm"\n', "radius_m = 0.015 for 1.5 cm"),
    ('[filter]\nunit = "mm"\n', "filter.radius_m"),
])
def test_a_radius_without_unit_is_refused_with_the_fix(tmp_path, text, fix):
    path = tmp_path / "old.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    message = str(info.value)
    assert "\n" not in message and str(path) in message and "has no unit" in message and fix in message
    with pytest.raises(ConfigError, match="filter.radius_m"):
        load_config(None, {"filter.radius": 0.02})


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ('[filter]\nradius_m = -1\n', "filter.radius_m"),
        ('[filter]\nradius_m = 1.3\n', "filter.radius_m"),  # 1.3 m: surely meant cm
        ('[estimator]\nname = "magic"\n', "estimator.name"),
        ('[geometry]\nmin_depth_m = 2.0\nmax_depth_m = 1.0\n', "max_depth_m"),
        ('[filter]\nradius_mm = 3\n', "filter.radius_mm"),
        ('[filter\n', "not valid TOML"),
    ],
)
def test_invalid_file_names_file_and_field(tmp_path, text, expected):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert str(path) in str(info.value)
    assert expected in str(info.value)


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        load_config(tmp_path / "nope.toml")


def test_a_field_set_by_an_option_is_named_by_the_option_and_a_file_field_by_the_file(tmp_path):
    from deploy.config import load_config
    from deploy.errors import ConfigError

    with pytest.raises(ConfigError, match=r"^invalid value for --distance: -0\.3: input should be greater than 0"):
        load_config(None, {"opening.target_distance_m": -0.3}, {"opening.target_distance_m": "--distance"})
    path = tmp_path / "run.toml"
    path.write_text("[opening]\ntarget_distance_m = -0.3\n")
    with pytest.raises(ConfigError, match=r"^invalid configuration in .*run\.toml: opening\.target_distance_m"):
        load_config(path, {"opening.target_distance_m": None}, {"opening.target_distance_m": "--distance"})
