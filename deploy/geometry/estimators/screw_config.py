"""Settings of the screw estimators (`screw`, `screw-grip`): the `[estimator.screw]` configuration section."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class ScrewConfig(BaseModel):
    """Registration, keyframe and joint-fit settings of `ScrewEstimator` and `ScrewGripEstimator`."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    voxel_m: float = Field(
        default=0.005, gt=0, le=0.05,
        description="m; voxel size the moving part is downsampled to before registration")
    max_source: int = Field(
        default=2000, gt=0, le=100_000,
        description="points; random subset (fixed seed) of a frame's part registered onto the keyframe")
    max_target: int = Field(
        default=6000, gt=0, le=100_000,
        description="points; random subset (fixed seed) of the keyframe's downsampled part used as target")
    min_points: int = Field(
        default=100, gt=0, le=100_000,
        description="points; a frame needs this many after downsampling to be registered")
    min_fitness: float = Field(
        default=0.3, gt=0, le=1,
        description="share (0-1) of a frame's source that must match the keyframe for the registration to count")
    keyframe_coverage: float = Field(
        default=0.8, gt=0, le=1,
        description="share (0-1); a frame becomes the next keyframe when the keyframe saw less than this of it")
    overlap_margin_m: float = Field(
        default=0.02, ge=0, le=0.2,
        description="m; how far outside the body box a point must have been to count as seen by the keyframe "
        "(at least the margin the moving part was cut with)")
    min_travel_m: float = Field(
        default=0.01, gt=0, le=1,
        description="m; part travel below this, with rotation below min_rotation_deg, gives no axis yet")
    min_rotation_deg: float = Field(
        default=2.0, gt=0, le=90,
        description="deg; part rotation below this, with travel below min_travel_m, gives no axis yet")
    noise_floor_m: float = Field(
        default=0.001, gt=0, le=0.1,
        description="m; registration noise, sigma0 of the BIC that chooses between prismatic and revolute")
    max_radius_m: float = Field(
        default=3.0, gt=0, le=100,
        description="m; a revolute axis farther than this from the moving part means prismatic (a wobbling drawer)")
    min_share: float = Field(
        default=0.5, ge=0, le=1,
        description="share (0-1); frames with fewer points than this share of the keyframe's are left out of the "
        "joint fit")
    part_noise_m: float = Field(
        default=0.003, gt=0, le=0.1,
        description="m; noise of the part centroid's registered positions (weights it against the gripper path)")
    grip_noise_m: float = Field(
        default=0.001, gt=0, le=0.1,
        description="m; noise of the gripper positions from forward kinematics (screw-grip only)")
    grip_gate_m: float = Field(
        default=0.005, gt=0, le=0.1,
        description="m; a gripper path missing its line or circle by more than this RMS (the grasp slipped) is "
        "left out (screw-grip only)")
