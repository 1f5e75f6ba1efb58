"""The rod scene file (TOML): schema, loading and conversion to a :class:`~magsoro.rod.Rod`.

Example (scenes/rod_cantilever.toml)::

    length = 0.0172
    youngs_modulus = 909e3
    field = [0.0, 0.0, 0.01]

    [cross_section]
    shape = "rectangle"
    width = 5e-3
    thickness = 0.84e-3

    [[magnetisation]]
    start = 0.0
    end = 0.0172
    remanence = [0.0, 0.0, 0.258]

Every key, its unit and its default are in the ``Field`` descriptions below (and in docs/rod.md).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, ValidationError, model_validator

from magsoro.config_errors import check_nesting, format_config_error
from magsoro.errors import SceneError
from magsoro.io.files import read_toml_file
from magsoro.rod.magnetisation import MagnetSegment
from magsoro.rod.model import DEFAULT_BASE_ROTATION, Rod
from magsoro.rod.section import CrossSection

def _as_tuple(v):
    """TOML arrays arrive as lists; the strict models want tuples for fixed-length vectors."""
    return tuple(v) if isinstance(v, list) else v


Vec3 = Annotated[tuple[float, float, float], BeforeValidator(_as_tuple)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)  # no "2e-4" -> 2e-4, no true -> 1.0


class CrossSectionConfig(_Strict):
    """``[cross_section]``: a rectangle (width along the material axis d1, thickness along d2) or a circle."""

    shape: Literal["rectangle", "circle"] = Field(
        "rectangle",
        description='Cross-section shape: "rectangle" (needs width, thickness) or "circle" (needs diameter). '
                    'Default "rectangle".')
    width: float | None = Field(None, gt=0, description="Rectangle width along d1, m. Required for a rectangle.")
    thickness: float | None = Field(None, gt=0, description=(
        "Rectangle thickness along d2 (the soft bending direction when thickness < width), m. Required "
        "for a rectangle."
    ))
    diameter: float | None = Field(None, gt=0, description="Circle diameter, m. Required for a circle.")

    @model_validator(mode="after")
    def _keys_match_shape(self):
        need = {"rectangle": ("width", "thickness"), "circle": ("diameter",)}[self.shape]
        for key in need:
            if getattr(self, key) is None:
                raise ValueError(f"shape = {self.shape!r} needs key {key!r} (m)")
        for key in {"width", "thickness", "diameter"} - set(need):
            if getattr(self, key) is not None:
                raise ValueError(f"key {key!r} does not apply to shape = {self.shape!r} (it takes {', '.join(need)})")
        return self

    def build(self) -> CrossSection:
        if self.shape == "rectangle":
            return CrossSection.rectangle(self.width, self.thickness)
        return CrossSection.circle(self.diameter)


class SegmentConfig(_Strict):
    """``[[magnetisation]]``: one uniformly magnetised stretch of the rod, start <= s < end."""

    start: float = Field(0.0, ge=0, description="Arc length where the segment starts, m from the clamp. Default 0.")
    end: float = Field(..., gt=0, description=(
        "Arc length where the segment ends, m from the clamp (<= length). Required."
    ))
    remanence: Vec3 = Field(..., description=(
        "Remanent flux density Br in the material frame (d1 width, d2 thickness, d3 axis), T. Required."
    ))


class RodConfig(_Strict):
    """A magnetic rod clamped at s = 0 (see docs/rod.md). SI units throughout."""

    length: float = Field(..., gt=0, description="Rod length L, m. Required.")
    cross_section: CrossSectionConfig = Field(..., description="Cross-section table, see CrossSectionConfig. Required.")
    youngs_modulus: float = Field(..., gt=0, description="Young's modulus E, Pa. Required.")
    shear_modulus: float | None = Field(None, gt=0, description=(
        "Shear modulus G, Pa. Default E/3 (incompressible elastomer)."
    ))
    density: float = Field(0.0, ge=0, description=(
        "Density of the rod material, kg/m^3; its weight acts along `gravity`. Default 0 (weightless)."
    ))
    gravity: Vec3 = Field((0.0, 0.0, -9.81), description="Gravitational acceleration, m/s^2. Default [0, 0, -9.81].")
    magnetisation: list[SegmentConfig] = Field(default_factory=list, description=(
        "Magnetised segments ([[magnetisation]] tables); uncovered stretches are unmagnetised. Default "
        "none."
    ))
    field: Vec3 = Field((0.0, 0.0, 0.0), description=(
        "Uniform applied field B, T (global frame). Default [0, 0, 0]; the CLI --field overrides it."
    ))
    perturbation: Vec3 | None = Field(None, description=(
        "Small field added during the solve and removed at the end, T; picks the buckling side when the "
        "field opposes the magnetisation. Default none."
    ))
    tip_force: Vec3 = Field((0.0, 0.0, 0.0), description=(
        "Dead force on the free end, N (global frame). Default [0, 0, 0]."
    ))
    tip_moment: Vec3 = Field((0.0, 0.0, 0.0), description=(
        "Couple on the free end, N m (global frame). Default [0, 0, 0]."
    ))
    base_position: Vec3 = Field((0.0, 0.0, 0.0), description="Clamp position p(0), m. Default [0, 0, 0].")
    base_rotation: Annotated[tuple[Vec3, Vec3, Vec3], BeforeValidator(_as_tuple)] = Field(
        tuple(tuple(r) for r in DEFAULT_BASE_ROTATION.tolist()),
        description=(
            "Clamp orientation R(0) as 3 rows; its columns are d1 (width), d2 (thickness), d3 (rod axis) "
            "in the global frame. Default [[0,0,1],[1,0,0],[0,1,0]]: axis along +x, thickness along z."
        ))
    extensible: bool = Field(False, description=(
        "false: Kirchhoff rod (inextensible, unshearable); true: extension E A and shear kappa G A "
        "included. Default false."
    ))
    n_nodes: int = Field(101, ge=2, le=100_000, description=(
        "Uniformly spaced output nodes along the rod (segment ends are added). Default 101."
    ))
    max_step: float | None = Field(None, gt=0, description="Largest integration step, m. Default length/100.")

    @model_validator(mode="after")
    def _segments_fit(self):
        for i, seg in enumerate(self.magnetisation):
            if not seg.start < seg.end:
                raise ValueError(f"magnetisation[{i}]: start ({seg.start} m) must be < end ({seg.end} m)")
            if seg.end > self.length * (1 + 1e-12):
                raise ValueError(f"magnetisation[{i}].end = {seg.end} m lies beyond length = {self.length} m")
        return self

    def build(self) -> Rod:
        """The :class:`Rod` this file describes."""
        return Rod(
            length=self.length,
            cross_section=self.cross_section.build(),
            youngs_modulus=self.youngs_modulus,
            shear_modulus=self.shear_modulus,
            magnetisation=[MagnetSegment(g.start, g.end, g.remanence) for g in self.magnetisation],
            density=self.density,
            gravity=self.gravity,
            tip_force=self.tip_force,
            tip_moment=self.tip_moment,
            base_position=self.base_position,
            base_rotation=np.array(self.base_rotation),
            extensible=self.extensible,
            n_nodes=self.n_nodes,
            max_step=self.max_step,
        )


def format_validation_error(exc: ValidationError, root: type[BaseModel] = None, source: str = "") -> str:
    """One line naming each bad key, what is wrong and (for unknown keys) the allowed ones."""
    return format_config_error(exc, root or RodConfig, source, vector_length=3)


def parse_rod_config(data: dict, source: str = "") -> RodConfig:
    """Validate a dict (e.g. parsed TOML); raises :class:`SceneError` with a one-line message."""
    check_nesting(data, source, SceneError)
    try:
        return RodConfig.model_validate(data)
    except ValidationError as exc:
        raise SceneError(format_validation_error(exc, RodConfig, source)) from None


def load_rod_config(path) -> RodConfig:
    """Read and validate a rod TOML file; raises :class:`SceneError` naming the file and the bad key."""
    path = Path(path)
    data = read_toml_file(path, SceneError, "rod file")
    return parse_rod_config(data, str(path))
