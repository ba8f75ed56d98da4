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


def test_unit_override_changes_the_radius():
    cfg = load_config(None, {"filter.profile": "sparse", "filter.unit": "mm"})
    assert cfg.filter.resolve().radius_m == pytest.approx(0.0013)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ('[filter]\nradius = -1\n', "filter.radius"),
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
