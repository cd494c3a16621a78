"""The parameters of the parabolic mirror (``params`` of ``kind: mirror``)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from .base import Strict

__all__ = ["MirrorParams"]


class MirrorParams(Strict):
    """``params`` of the parabolic mirror (``kind: mirror``)."""

    kind: Literal["mirror"] = Field("mirror", description="the task kind this group belongs to")
    focus: float = Field(1.0, gt=0, description="height F of the focus (0, F); the exact mirror is x^2 / (4 F)")
    x_min: float = Field(-1.0, description="left end of the aperture")
    x_max: float = Field(1.0, description="right end of the aperture")
    n_samples: int = Field(256, gt=0, description="ray positions per iteration")
    sampling: Literal["uniform", "stratified"] = Field(
        "stratified", description="uniform: i.i.d. uniform ray positions; stratified: one uniform point per equal cell")
    reflection_weight: float = Field(1.0, ge=0, description="weight of the optics loss (the interface weight is losses.interface)")
    reflection_start: int = Field(0, ge=0, description="first iteration of the optics loss")
    n_eval: int = Field(2001, ge=2, description="grid points for the error against the exact parabola")
    n_rays_plot: int = Field(15, ge=1, description="rays drawn in the figure")

    @model_validator(mode="after")
    def _aperture(self) -> MirrorParams:
        if not self.x_min < self.x_max:
            raise ValueError("x_min must be smaller than x_max")
        return self
