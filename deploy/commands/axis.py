"""`deploy axis fit-trajectory|estimate|demo`: joint axes from trajectories, recordings or synthetic scenes."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from deploy.commands.options import EstimatorOpt, JointChoice, JsonOpt
from deploy.commands.output import fmt, print_json, print_rows, print_table

app = typer.Typer(help="Estimate joint axes from recordings, gripper trajectories or synthetic scenes.",
                  no_args_is_help=True)


ConfigOpt = Annotated[Path | None, typer.Option("--config", help="TOML config file (see docs/cli.md).")]


def _print_axis(title: str, data: dict) -> None:
    """The axis fields of `data` that are set: vectors and floats with 4 decimals."""
    rows = {}
    for key in ("joint_type", "origin", "direction", "radius", "residual_m", "n_samples", "estimator", "reason"):
        value = data.get(key)
        if isinstance(value, list):
            value = "[" + ", ".join(f"{v:+.4f}" for v in value) + "]"
        elif isinstance(value, float):
            value = f"{value:.4f}"
        if value is not None:
            rows[key] = value
    print_rows(title, rows, digits=None)


@app.command("fit-trajectory")
def axis_fit_trajectory(
    file: Annotated[Path, typer.Argument(help="One sample per line: `x y z` or `x y z qx qy qz qw` (m).")],
    joint: Annotated[JointChoice, typer.Option(help="Joint type, or auto to choose by BIC.")] = JointChoice.auto,
    json_out: JsonOpt = False,
) -> None:
    """Fit a prismatic line or a revolute axis to a gripper (handle) trajectory.

    Example: deploy axis fit-trajectory handle.txt --joint auto --json
    """
    from deploy.errors import RecordingError
    from deploy.geometry.estimators.trajectory import fit_trajectory, parse_trajectory_text
    from deploy.geometry.types import JointType

    if not file.is_file():
        raise RecordingError(f"trajectory file {file} not found: give a text file with one `x y z` per line")
    try:
        positions, quats = parse_trajectory_text(file.read_text())
    except ValueError as exc:
        raise RecordingError(f"trajectory file {file}: {exc}") from exc
    result = fit_trajectory(positions, quats, None if joint == JointChoice.auto else JointType(joint.value))
    data = {"joint_type": None, "origin": None, "direction": None, "radius": None, "residual_m": None,
            "n_samples": len(positions)}
    if hasattr(result, "reason"):
        data["reason"] = result.reason
    else:
        data.update({k: v for k, v in result.to_dict().items() if k in data})
    if json_out:
        print_json(data)
    else:
        _print_axis(f"axis fitted to {file}", data)
    if "reason" in data:
        raise typer.Exit(1)


@app.command("estimate")
def axis_estimate(
    recording: Annotated[Path, typer.Argument(help="Frames directory with masks (docs/recording-format.md).")],
    joint: Annotated[JointChoice, typer.Option(help="Joint type, or auto to classify.")] = JointChoice.auto,
    estimator: EstimatorOpt = None,
    filter_profile: Annotated[str | None, typer.Option("--filter", help="Filter profile: sim or sparse.")] = None,
    filter_radius: Annotated[float | None, typer.Option(help="Filter radius, in --filter-unit.")] = None,
    filter_eps: Annotated[int | None, typer.Option(help="Minimum number of other points within the radius.")] = None,
    filter_unit: Annotated[str | None, typer.Option(help="Unit of --filter-radius: m, cm or mm.")] = None,
    config: ConfigOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Estimate the joint axis from a recording, re-estimating over a sliding window at every frame.

    Examples:
      deploy axis estimate runs/drawer --json
      deploy axis estimate rec/ --estimator paper-obb --joint prismatic --filter sparse
    """
    from deploy.config import load_config
    from deploy.estimate_recording import estimate_recording

    cfg = load_config(config, {
        "estimator.name": estimator,
        "estimator.joint": joint.value if joint != JointChoice.auto else None,
        "filter.profile": filter_profile, "filter.radius": filter_radius, "filter.eps": filter_eps,
        "filter.unit": filter_unit,
    })
    data = estimate_recording(recording, cfg)
    if json_out:
        print_json(data)
    else:
        _print_axis(f"axis of {recording} ({data['frame']} frame)", data)
    if data["joint_type"] is None:
        raise typer.Exit(1)


@app.command("demo")
def axis_demo(seed: Annotated[int, typer.Option(help="Random seed of the synthetic scenes.")] = 0) -> None:
    """Synthetic noisy drawer and door: every estimator's axis error in one table.

    Example: deploy axis demo --seed 3
    """
    from deploy.bench.axis import demo_axis

    rows = []
    for r in demo_axis(seed):
        ms = sum(r.ms_per_estimate) / max(len(r.ms_per_estimate), 1)
        rows.append((r.kind, r.estimator, fmt(r.angle_deg) if r.angle_deg is not None else f"- ({r.reason})",
                     fmt(r.position_m, 100), "ok" if r.joint_type_ok else "wrong", f"{ms:.1f}"))
    print_table("axis estimators on a synthetic drawer (10 cm) and door (20 deg), D415-like noise",
                ("object", "estimator", "angle error (deg)", "position error (cm)", "auto joint type", "ms"), rows)
