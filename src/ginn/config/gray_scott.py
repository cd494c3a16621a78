"""The parameters of the Gray-Scott generative PINN (``params`` of ``kind: gray-scott``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pydantic import Field

from .base import LossTerm, Strict

__all__ = ["GSParams", "GrayScottLosses", "GrayScottParams"]


@dataclass(frozen=True)
class GSParams:
    """Coefficients of the Gray-Scott equation (defaults: the paper's Appendix A.6)."""

    D_v: float = 1.2e-5
    D_u: float = 2.4e-5
    alpha: float = 0.028
    beta: float = 0.057


class GrayScottLosses(Strict):
    """Weights and start iterations of the three Gray-Scott loss terms."""

    residual: LossTerm = LossTerm(weight=1.0)
    gradient: LossTerm = LossTerm(weight=1e-4)
    diversity: LossTerm = LossTerm(weight=1e-7)


class GrayScottParams(Strict):
    """``params`` of the Gray-Scott generative PINN (``kind: gray-scott``); see docs/gray-scott.md."""

    kind: Literal["gray-scott"] = Field("gray-scott", description="the task kind this group belongs to")
    D_v: float = Field(1.2e-5, gt=0, description="diffusion coefficient of v")
    D_u: float | None = Field(None, gt=0, description="diffusion coefficient of u (None: 2 D_v)")
    alpha: float = Field(0.028, gt=0, description="feed rate")
    beta: float = Field(0.057, gt=0, description="kill rate")
    grid: int = Field(64, ge=8, description="training grid points per axis")
    fine_grid: int = Field(
        0, ge=0, description="from iteration fine_grid_from on, train on this grid instead of `grid` (0: never); a "
        "finer grid holds the pattern's harmonics above the coarse grid's Nyquist frequency")
    fine_grid_from: int = Field(0, ge=0, description="first iteration on `fine_grid`")
    translate: bool = Field(True, description="translate the training grid randomly every iteration")
    derivatives: Literal["fd", "spectral", "autograd"] = Field(
        "fd", description="periodic finite differences, FFT on the same grid, or autograd through ginn.fields")
    gradient_cap: float = Field(1.0, gt=0, description="the gradient reward saturates at this mean |grad|^2")
    diversity_distance: Literal["rms", "shift"] = Field(
        "rms", description="rms: RMS difference of v; shift: its minimum over the grid's periodic translations")
    residual_gradient: Literal["full", "flow", "step"] = Field(
        "full", description="full: gradient of mean(R^2) (the paper); flow: descend along the PDE's own time derivative R; "
        "step: regress on the sampled state advanced by a semi-implicit pseudo-time step")
    flow_steps: int = Field(0, ge=0, description="with residual_gradient=flow/step: switch to full after this many iterations (0: never)")
    step_dt: float = Field(1.0, gt=0, description="pseudo-time sub-step of residual_gradient=step")
    step_count: int = Field(10, ge=1, description="sub-steps per target of residual_gradient=step (target time step_dt * step_count)")
    step_sobolev: float = Field(
        0.0, ge=0, description="residual_gradient=step: add this weight times mean |D lap (W - target)|^2 (D = D_u, D_v) "
        "to the regression, so that the network's error is also weighted where diffusion amplifies it into the residual")
    step_reuse: int = Field(
        1, ge=1, description="residual_gradient=step: iterations that regress on one target (computed every step_reuse "
        "iterations and moved to each iteration's translated grid by an exact Fourier shift)")
    u_offset: float = Field(0.0, description="u = u_offset + network output (0: the paper's raw output)")
    v_offset: float = Field(0.0, description="v = v_offset + network output")
    output_scale: float = Field(1.0, gt=0, description="u = u_offset + output_scale * network output (same for v)")
    losses: GrayScottLosses = GrayScottLosses()
    resolution: int = Field(256, ge=8, description="resolution of the written fields and pictures")
    n_interpolation: int = Field(8, ge=2, description="patterns in the latent interpolation strip")

    @property
    def gs(self) -> GSParams:
        """The equation's coefficients (``D_u`` defaults to ``2 D_v``)."""
        return GSParams(D_v=self.D_v, D_u=self.D_u if self.D_u is not None else 2.0 * self.D_v,
                        alpha=self.alpha, beta=self.beta)
