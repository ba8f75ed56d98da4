"""Typed configuration: TOML files validated by pydantic, with CLI overrides on top.

A file holds any subset of the sections below; everything has a default, so no file is needed:

    [filter]            # radius outlier filter of the object cloud (profile "sim" or "sparse")
    profile = "sim"
    [geometry]
    box = "yaw"         # body box: "yaw" (paper) or "oriented" (full 3D)
    [estimator]
    name = "screw-grip"
    joint = "auto"
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from deploy.errors import ConfigError
from deploy.geometry.radius_filter import FILTER_PROFILES, FilterProfile

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class FilterConfig(_Section):
    """Radius outlier filter: keep a point with at least `eps` other points within `radius` `unit`s.

    `profile` fills in whichever of radius / eps / unit is not given.
    """

    profile: Literal["sim", "sparse"] = "sim"
    radius: float | None = Field(default=None, gt=0)
    eps: int | None = Field(default=None, ge=1)
    unit: Literal["m", "cm", "mm"] | None = None

    def resolve(self) -> FilterProfile:
        base = FILTER_PROFILES[self.profile]
        return FilterProfile(
            radius=base.radius if self.radius is None else self.radius,
            eps=base.eps if self.eps is None else self.eps,
            unit=base.unit if self.unit is None else self.unit,
        )


class GeometryConfig(_Section):
    """Body box and moving-part extraction."""

    box: Literal["yaw", "oriented"] = "yaw"
    remove_handle: bool = True
    body_margin_m: float = Field(default=0.01, ge=0, le=0.1)
    inside_depth_m: float = Field(
        default=1.0, ge=0, le=5, description="doors (estimator.joint revolute): the moving part is cut out "
        "by the body box reaching this far behind the front, because the cabinet's inside that an opening "
        "door reveals does not move (a drawer's revealed inside is the drawer)")
    min_depth_m: float = Field(default=0.1, ge=0)
    max_depth_m: float = Field(default=3.0, gt=0)
    decimation: int = Field(default=2, ge=1, le=8, description="use every n-th pixel in each direction")

    @model_validator(mode="after")
    def _depth_range(self) -> GeometryConfig:
        if self.max_depth_m <= self.min_depth_m:
            raise ValueError("max_depth_m must be larger than min_depth_m")
        return self


class EstimatorConfig(_Section):
    """Which axis estimator runs, over how many frames, for which joint type."""

    name: Literal["paper-obb", "screw", "screw-grip", "trajectory"] = "screw-grip"
    joint: Literal["auto", "prismatic", "revolute"] = "auto"
    window: int = Field(default=10, ge=2, le=100)


class Config(_Section):
    filter: FilterConfig = FilterConfig()
    geometry: GeometryConfig = GeometryConfig()
    estimator: EstimatorConfig = EstimatorConfig()


def _set_dotted(data: dict[str, Any], dotted: str, value: Any) -> None:
    section, _, key = dotted.partition(".")
    data.setdefault(section, {})[key] = value


def load_config(path: Path | None = None, overrides: dict[str, Any] | None = None) -> Config:
    """Load `path` (TOML) if given, apply `overrides` ({"filter.radius": 1.3, ...}; None values are
    skipped) and validate. Raises ConfigError naming the file, the field and the problem."""
    data: dict[str, Any] = {}
    source = "command-line options"
    if path is not None:
        path = Path(path)
        source = str(path)
        if not path.is_file():
            raise ConfigError(f"config file {path} not found: check the path or omit --config to use defaults")
        try:
            data = tomllib.loads(path.read_text())
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"config file {path} is not valid TOML: {exc}") from exc
    for dotted, value in (overrides or {}).items():
        if value is not None:
            _set_dotted(data, dotted, value)
    try:
        return Config.model_validate(data)
    except ValidationError as exc:
        problems = "; ".join(
            f"{'.'.join(str(p) for p in err['loc'])}: {err['msg']}" for err in exc.errors()
        )
        raise ConfigError(f"invalid configuration in {source}: {problems}") from exc
