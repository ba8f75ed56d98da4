"""report.png of an episode: the axis acted on at each step drawn over the first colour frame, the opening over
arm time, and (in simulation) the axis error per step."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from deploy.control.state import EpisodeResult
from deploy.geometry.cloud import points_to_pixels

AXIS_HALF_LENGTH_M = 0.4  # drawn axis segments reach this far either side of the origin


def write_report(path: Path, result: EpisodeResult, errors: list[tuple[float, float | None] | None],
                 truth: bool = True) -> None:
    """Three panels: axis per step over the first frame, opening vs time, axis error per step."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    first_frame = result.first_frame
    fig, (ax_img, ax_open, ax_err) = plt.subplots(1, 3, figsize=(15, 4.2))
    axes = [(e["step"], e["axis"]) for e in result.estimates if e["axis"] is not None]
    if first_frame is not None:
        ax_img.imshow(first_frame.color)
        norm = plt.Normalize(axes[0][0], max(axes[-1][0], axes[0][0] + 1)) if axes else None
        for step, axis in axes:
            o, d = np.array(axis["origin"]), np.array(axis["direction"])
            uv = points_to_pixels(np.array([o - AXIS_HALF_LENGTH_M * d, o + AXIS_HALF_LENGTH_M * d]),
                                  first_frame.intrinsics.K, first_frame.T_base_camera,
                                  first_frame.intrinsics.dist_coeffs)
            ax_img.plot(uv[:, 0], uv[:, 1], color=plt.cm.viridis(norm(step)), lw=1.5)
        h, w = first_frame.color.shape[:2]
        ax_img.set_xlim(0, w)
        ax_img.set_ylim(h, 0)
        if axes:  # a colour bar reads at any step count, where a legend of every step did not
            bar = fig.colorbar(plt.cm.ScalarMappable(norm, "viridis"), ax=ax_img, label="step", fraction=0.05)
            bar.ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax_img.set_title(f"axis estimates ({result.stop_reason.value})")
    ax_img.axis("off")
    if result.opening_curve:
        t, opened = np.array(result.opening_curve).T
        ax_open.plot(t, opened * result.scale, "o-")
    ax_open.axhline(result.target * result.scale, color="k", ls="--", lw=1)
    unit = "deg" if result.joint_type == "revolute" else "m"
    ax_open.set(xlabel="arm time (s)", ylabel=f"estimated opening ({unit})", title="opening vs time")
    rows = [(e["step"], err) for e, err in zip(result.estimates, errors, strict=True) if err is not None]
    if rows:
        steps = [s for s, _ in rows]
        ax_err.plot(steps, [err[0] for _, err in rows], "o-", label="angle (deg)")
        if result.joint_type == "revolute":  # a line's position along itself means nothing for a drawer
            ax_err.plot(steps, [err[1] * 100 for _, err in rows], "s-", label="position (cm)")
        ax_err.legend()
        ax_err.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax_err.set(xlabel="step", title="axis error per step" if rows else
               "axis error (no axis estimated)" if truth else "axis error (no truth)")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
