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


def test_a_runs_config_json_given_to_config_is_named_json_not_a_toml_syntax_error(capsys, tmp_path, monkeypatch):
    """`--config RUN/config.json` (the run's record of its settings): say it is JSON and what --config takes,
    whatever the file is called; not "is not valid TOML (Invalid statement ...): fix the syntax"."""
    from cli_run import one_line, run

    from deploy.report.run_folder import RunFolder

    RunFolder(tmp_path / "run").write_config(Config())
    record = tmp_path / "run" / "config.json"
    renamed = tmp_path / "settings.toml"
    renamed.write_text(record.read_text())
    for path in (record, renamed):
        with pytest.raises(ConfigError) as info:
            load_config(path)
        assert str(info.value) == (
            f"config file {path} is JSON, not TOML: --config takes a TOML run config, not a run's record of the "
            "settings it used (RUN/config.json); write the settings to change in a .toml file "
            "(docs/quickstart.md#configuration shows the sections), or omit --config for the defaults")
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, "open-drawer", "--config", record)
    assert code == 2 and "is JSON, not TOML: --config takes a TOML run config" in one_line(err)
    (tmp_path / "bad.toml").write_text("[filter\n")  # TOML that is not JSON either: the syntax error, as before
    with pytest.raises(ConfigError, match="is not valid TOML"):
        load_config(tmp_path / "bad.toml")


def test_an_unknown_estimator_lists_the_valid_names_and_no_range():
    with pytest.raises(ConfigError) as info:
        load_config(None, {"estimator.name": "bogus"}, {"estimator.name": "--estimator"})
    assert str(info.value) == ("invalid value for --estimator (estimator.name): unknown estimator 'bogus': choose "
                               "one of screw-grip, screw, trajectory, paper-obb")
