"""Checks that a problem's geometry has the symmetry its spec states (else no shape can)."""

from __future__ import annotations

from collections.abc import Sequence

import torch

from ..errors import SpecError
from ..geometry.base import Box, Interface, Region
from ..geometry.sampling import sample_box, sample_interfaces
from ..geometry.symmetry import Symmetry

_SAMPLES = 4096


def check_symmetric(symmetry: Symmetry, domain: Box, design: Region | None, interfaces: Sequence[Interface],
                    tol: float) -> None:
    """Raise :class:`SpecError` (one line) when the design region (obstacles removed) or the
    interfaces differ from their image under a generator of ``symmetry`` by more than ``tol``.

    The design region is compared by its signed distance at uniform points of the domain, the
    interfaces by the distance of their mapped samples to the interfaces (float64, fixed seed).
    """
    gen = torch.Generator().manual_seed(0)
    x = sample_box(domain, _SAMPLES, gen, dtype=torch.float64)
    y = sample_interfaces(tuple(interfaces), _SAMPLES, gen, dtype=torch.float64)[0] if interfaces else None
    for name, T in symmetry.generators():
        if design is not None:
            gap = (design.sdf(T(x)) - design.sdf(x)).abs()
            if float(gap.max()) > tol:
                i = int(gap.argmax())
                raise SpecError(f"spec field 'symmetry': the design region is not symmetric under {name} (its signed "
                                f"distance changes by {float(gap[i]):.3g} at {_fmt(x[i])}; tolerance {tol:.3g})")
        if y is not None:
            ty = T(y)
            gap = torch.stack([f.distance(ty) for f in interfaces]).min(dim=0).values
            if float(gap.max()) > tol:
                i = int(gap.argmax())
                raise SpecError(f"spec field 'symmetry': the interfaces are not symmetric under {name} (the image of "
                                f"{_fmt(y[i])} lies {float(gap[i]):.3g} from them; tolerance {tol:.3g})")


def _fmt(p) -> str:
    return "(" + ", ".join(f"{float(v):.3g}" for v in p) + ")"
