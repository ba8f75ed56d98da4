"""`deploy axis fit-trajectory|estimate|demo`: joint axes from trajectories, recordings or synthetic scenes."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Annotated

import typer

from deploy.commands.options import (
    ConfigFileOpt,
    EstimatorOpt,
    FilterChoice,
    JointChoice,
    JsonOpt,
    UpChoice,
    view_option,
)
from deploy.commands.output import err_console, fmt, print_json, print_rows, print_table, progress_bar, view_file

app = typer.Typer(help="Estimate joint axes from recordings, gripper trajectories or synthetic scenes.",
                  no_args_is_help=True)


ViewOpt = view_option("the frames, masks, gripper path and the axis estimated at each frame (saved to --rrd)")
RrdOpt = Annotated[Path | None, typer.Option(
    "--rrd", metavar="PATH", help="Where --view saves the rerun file (implies --view) \\[default: "
    "runs/REC-axis.rrd (REC-axis-2.rrd, ... when taken), REC being the recording folder's name (a run folder's for "
    "RUN/frames); never inside the recording, which may be read-only].")]


AXIS_FIELDS = ("joint_type", "origin", "direction", "direction_sigma_deg", "radius_m", "residual_m", "n_samples",
               "from_frame", "format", "estimator", "reason", "rrd")


def _print_axis(title: str, items: Iterable[tuple[str, object]]) -> None:
    """The fields that are set, as rows: vectors and floats with 4 decimals (a key shown once)."""
    rows: dict[str, object] = {}
    for key, value in items:
        if isinstance(value, list):
            value = "[" + ", ".join(f"{v:+.4f}" for v in value) + "]"
        elif isinstance(value, float):
            value = f"{value:.4f}"
        if value is not None:
            rows.setdefault(key, value)
    print_rows(title, rows, digits=None)


@app.command("fit-trajectory")
def axis_fit_trajectory(
    file: Annotated[Path, typer.Argument(help="One sample per line: `x y z`, `x y z qx qy qz qw`, TUM `timestamp tx ty "
                                              "tz qx qy qz qw`, or CSV with a header naming x,y,z (m) and optionally "
                                              "qx,qy,qz,qw and timestamp.")],
    joint: Annotated[JointChoice, typer.Option(
        help="Joint type, or auto: decided from the path, or undecided (exit 1, with the reason).")] = JointChoice.auto,
    up: Annotated[UpChoice, typer.Option(
        help="The world's up axis in the file's frame: a hinge found near vertical or horizontal is levelled toward "
             "it by a 1.5 deg prior (furniture is built level); none for an unknown frame or a hinge built at a "
             "slant.")] = UpChoice.z,
    orientations: Annotated[bool, typer.Option(
        help="Fit the file's orientations too (the turn about the hinge): right for a handle tracked on the part; "
             "--no-orientations for a gripper's path (a recording's tool.txt), whose fingers let the handle turn in "
             "them, so that its turn is not the part's.")] = True,
    json_out: JsonOpt = False,
) -> None:
    """Fit a prismatic line or a revolute axis to a gripper (handle) trajectory, with the uncertainty of its direction.

    Example: deploy axis fit-trajectory handle.txt --joint auto --json
    Example: deploy axis fit-trajectory handle_tum.txt --up y
    Example: deploy axis fit-trajectory export/tool.txt --no-orientations
    """
    import numpy as np

    from deploy.errors import RecordingError
    from deploy.geometry.estimators.trajectory import fit_trajectory_report, parse_trajectory
    from deploy.geometry.types import JointType

    if not file.is_file():
        raise RecordingError(f"trajectory file {file} not found: give a text file with one `x y z` per line")
    try:
        text = file.read_text(encoding="utf-8-sig")  # a spreadsheet's CSV starts with a byte-order mark
    except UnicodeDecodeError as exc:
        raise RecordingError(f"trajectory file {file} is not UTF-8 text ({exc.reason} at byte {exc.start}): give a "
                             "text file with one `x y z` per line") from None
    try:
        samples = parse_trajectory(text)
    except ValueError as exc:
        raise RecordingError(f"trajectory file {file}: {exc}") from exc
    if len(samples.positions) < 3:
        raise RecordingError(f"trajectory file {file} holds {len(samples.positions)} sample(s) but a fit needs at "
                             "least 3: give one `x y z` per line (or a CSV header and rows) for 3 or more positions")
    world_up = None if up is UpChoice.none else np.eye(3)["xyz".index(up.value)]
    data = fit_trajectory_report(samples.positions, samples.quaternions if orientations else None,
                                 None if joint == JointChoice.auto else JointType(joint.value), times=samples.times,
                                 up=world_up)
    data.update(n_samples=len(samples.positions), format=samples.format, up=up.value,
                orientations=orientations and samples.quaternions is not None)  # and confidence, noise_m, ...
    if json_out:
        print_json(data)
    else:
        details = data.get("details", {}).items()  # an undecided answer's evidence
        _print_axis(f"axis fitted to {file}", [*((k, v) for k, v in data.items() if k not in ("details", "undecided")),
                                               *details])
    if "reason" in data:
        raise typer.Exit(1)


ESTIMATE_OPTIONS = {"estimator.name": "--estimator", "estimator.joint": "--joint", "filter.profile": "--filter",
                    "filter.radius_m": "--filter-radius-m", "filter.eps": "--filter-eps"}
"""The `axis estimate` options that set these config fields (error messages name the option)."""


@app.command("estimate")
def axis_estimate(
    recording: Annotated[Path, typer.Argument(help="Frames directory with masks (docs/recording-format.md).")],
    joint: Annotated[JointChoice, typer.Option(help="Joint type, or auto to classify.")] = JointChoice.auto,
    estimator: EstimatorOpt = None,
    filter_profile: Annotated[FilterChoice | None, typer.Option(
        "--filter", help="Filter profile: sparse (the paper's real-camera setting) or sim \\[default: the config's, "
        "else sim for a recording made in simulation, sparse otherwise].")] = None,
    filter_radius_m: Annotated[float | None, typer.Option(
        "--filter-radius-m", help="Filter radius in metres (the paper's real-camera 1.3 cm: 0.013) \\[default: the "
        "profile's].")] = None,
    filter_eps: Annotated[int | None, typer.Option(help="Minimum number of other points within the radius.")] = None,
    config: ConfigFileOpt = None,
    view: ViewOpt = False,
    rrd: RrdOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Estimate the joint axis from a recording, re-estimating over a sliding window at every frame (with the
    gripper's path where the recording has it, e.g. from `deploy record --arm`).

    Examples:
      deploy axis estimate runs/drawer --json
      deploy axis estimate rec/ --estimator paper-obb --joint prismatic --filter sparse
    """
    from deploy.config import load_config
    from deploy.estimate_recording import estimate_recording

    cfg = load_config(config, {
        "estimator.name": estimator,
        "estimator.joint": joint.value if joint != JointChoice.auto else None,
        "filter.profile": filter_profile.value if filter_profile is not None else None,
        "filter.radius_m": filter_radius_m, "filter.eps": filter_eps,
    }, ESTIMATE_OPTIONS).for_camera(f"replay:{recording}")
    viewer = None
    if view or rrd is not None:
        from deploy.report.viewer import RerunViewer

        viewer = RerunViewer(view_file(recording, rrd, "axis"))
    with progress_bar(f"estimating {recording.name}") as bar:
        data = estimate_recording(recording, cfg, progress=bar.counts, viewer=viewer)
    if viewer is not None:
        data["rrd"] = str(viewer.path)
    if json_out:
        print_json(data)
    else:
        _print_axis(f"axis of {recording} ({data['frame']} frame)", ((k, data.get(k)) for k in AXIS_FIELDS))
    if data["joint_type"] is None:
        raise typer.Exit(1)


@app.command("demo")
def axis_demo(
    seed: Annotated[int, typer.Option(min=0, help="Random seed of the synthetic scenes.")] = 0,
    json_out: JsonOpt = False,
) -> None:
    """Synthetic noisy drawer and door: every estimator's axis error in one table.

    Example: deploy axis demo --seed 3 --json
    """
    from deploy.bench.axis import demo_axis

    rows, results = [], []
    with err_console.status("axis demo: every estimator on a synthetic drawer and door"):
        demo = demo_axis(seed)
    for r in demo:
        ms = sum(r.ms_per_estimate) / max(len(r.ms_per_estimate), 1)
        results.append({"object": r.kind, "estimator": r.estimator, "angle_error_deg": r.angle_deg,
                        "position_error_m": r.position_m, "joint_type_ok": r.joint_type_ok, "ms_per_estimate": ms,
                        "reason": r.reason})
        rows.append((r.kind, r.estimator, fmt(r.angle_deg) if r.angle_deg is not None else f"- ({r.reason})",
                     fmt(r.position_m, 100), "ok" if r.joint_type_ok else "wrong", f"{ms:.1f}"))
    if json_out:
        print_json({"seed": seed, "results": results})
        return
    print_table("axis estimators on a synthetic drawer (10 cm) and door (20 deg), D415-like noise",
                ("object", "estimator", "angle error (deg)", "position error (cm)", "auto joint type", "ms"), rows)
