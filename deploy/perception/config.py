"""Perception settings: which backend, which prompts and models, and when a track counts as lost."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

DEFAULT_DETECTOR = "IDEA-Research/grounding-dino-tiny"
DEFAULT_TRACKER = "facebook/sam2.1-hiera-tiny"
EDGETAM_TRACKER = "yonigozlan/EdgeTAM-hf"


class PerceptionConfig(BaseModel):
    """Settings of every segmenter backend (each reads the fields it needs).

    detector / tracker: a local directory or a Hugging Face repo id looked up in the local cache
    (never downloaded here: fetch with `hf download REPO_ID`). box: first-frame box (x0, y0, x1, y1)
    in pixels; with it the detector is skipped. point: the pixel (u, v) on the part to open in the first frame
    (segmenters get it as a `Pointer`).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    object_prompt: str = "cabinet"
    handle_prompt: str | None = "handle"
    detector: str = DEFAULT_DETECTOR
    tracker: str = DEFAULT_TRACKER
    device: Literal["auto", "cuda", "mps", "cpu"] = "auto"
    box_threshold: float = Field(default=0.25, ge=0, le=1)
    text_threshold: float = Field(default=0.3, ge=0, le=1)
    box: tuple[float, float, float, float] | None = None
    point: tuple[float, float] | None = Field(default=None, description="the pixel (u, v) the user pointed at on the "
                                              "part to open in the first frame")
    min_area_ratio: float = Field(default=0.3, ge=0, le=1, description="lost below this x the first mask's area")
    min_iou: float = Field(default=0.3, ge=0, le=1, description="lost below this IoU with the previous mask")
    max_redetections: int = Field(default=3, ge=0, description="re-detection attempts on a lost frame before stopping")
    detect_min_range_m: float = Field(default=0.25, ge=0, description="rgbd: the object stands at least this far "
                                      "from the arm's base (horizontally)")
    detect_max_range_m: float = Field(default=1.5, gt=0, description="rgbd: ... and at most this far")
    track_margin_m: float = Field(default=0.02, ge=0, le=0.2, description="rgbd: the tracking region's margin "
                                  "around the detected object")
    opening_reach_m: float = Field(default=0.6, ge=0, le=2.0, description="rgbd: how far the opening part may "
                                   "come out of the front (a door's width, if larger, counts)")


def perception_config(**overrides: object) -> PerceptionConfig:
    """A PerceptionConfig from the non-None `overrides` (CLI options); invalid values are a ConfigError."""
    from pydantic import ValidationError

    from deploy.errors import ConfigError

    try:
        return PerceptionConfig(**{k: v for k, v in overrides.items() if v is not None})
    except ValidationError as e:
        problems = "; ".join(f"{'.'.join(map(str, err['loc']))}: {err['msg']}" for err in e.errors())
        raise ConfigError(f"invalid perception option(s): {problems}; see `deploy track --help`") from None
