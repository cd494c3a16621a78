"""Overhangs of an extracted boundary for additive manufacturing.

A surface printed layer on layer along the build direction ``up`` supports itself while it faces
down by at most an angle ``theta`` below the horizontal; steeper down-facing surfaces need support.
With ``n`` the outward unit normal of a boundary element, the element faces down where
``n . up < 0`` and *overhangs* where ``-n . up > sin(theta)``. A sphere overhangs on the cap of
half-angle ``90 - theta`` round its lowest point: ``1 - sin(theta)`` of its down-facing area; a
circle (2D) on the arc of ``2 (90 - theta)`` degrees, ``1 - theta / 90`` of its lower half.

Elements are exempt where a part may face down at any angle: on the build plate (the height
``plate`` along ``up``, within ``tol``) and at the interfaces (within ``tol`` of one, or realising
one farther away, :func:`realising_elements`), as are the caps where the domain cuts the shape (not
a surface of the part). The share is taken over the down-facing area that is not exempt.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import torch

from ..geometry.base import Interface, near_any_interface, nearest_interface_points
from .boundary import Boundary

__all__ = ["element_normals", "overhang_share", "exempt_elements", "realising_elements"]


def element_normals(boundary: Boundary) -> np.ndarray:
    """Outward unit normals of the elements, ``(m, d)``: right of each segment in 2D (the shape is
    on its left), the right-hand normal of each triangle in 3D (outward orientation)."""
    V, E = boundary.vertices, boundary.elements
    if boundary.dim == 2:
        t = V[E[:, 1]] - V[E[:, 0]]
        n = np.stack([t[:, 1], -t[:, 0]], axis=1)
    else:
        n = np.cross(V[E[:, 1]] - V[E[:, 0]], V[E[:, 2]] - V[E[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def exempt_elements(boundary: Boundary, up: np.ndarray, plate: float, tol: float,
                    interfaces: Sequence[Interface] = ()) -> np.ndarray:
    """``(m,)`` bool: the elements on the build plate (centroid within ``tol`` of the height
    ``plate`` along ``up``), within ``tol`` of an interface, or on a cap of the domain."""
    V, E = boundary.vertices, boundary.elements
    c = V[E].mean(axis=1)
    out = np.abs(c @ up - plate) <= tol
    out |= ~boundary.level_set_elements()
    if len(c) and interfaces:
        with torch.no_grad():
            out |= near_any_interface(interfaces, torch.as_tensor(c, dtype=torch.float64), tol).cpu().numpy()
    return out


def realising_elements(boundary: Boundary, interfaces: Sequence[Interface], tol: float,
                       among: np.ndarray | None = None) -> np.ndarray:
    """``(m,)`` bool: the elements (of the mask ``among``) that realise an interface: their centroid
    ``c`` is, within ``tol``, as near as the boundary comes to the interface point ``q`` nearest
    to ``c``: ``|c - q| <= tol + dist(q, boundary)``. Within ``tol`` of an interface every element
    does; farther, the elements where the boundary follows an interface it has not reached."""
    out = np.zeros(boundary.n_elements, dtype=bool)
    if not interfaces or boundary.n_elements == 0:
        return out
    idx = np.flatnonzero(np.ones(boundary.n_elements, dtype=bool) if among is None else among)
    if idx.size == 0:
        return out
    c = boundary.vertices[boundary.elements[idx]].mean(axis=1)
    with torch.no_grad():
        d, q = nearest_interface_points(interfaces, torch.as_tensor(c, dtype=torch.float64))
    d, q = d.cpu().numpy(), q.cpu().numpy()
    ok = np.isfinite(d)
    reach = np.full(idx.size, -np.inf)
    reach[ok] = tol + boundary.distance(q[ok])
    out[idx] = d <= reach
    return out


def overhang_share(boundary: Boundary, up: Sequence[float], angle: float, exempt: np.ndarray | None = None) -> float | None:
    """The share of the down-facing boundary (length in 2D, area in 3D; ``exempt`` elements left
    out) that faces down by more than ``angle`` degrees below the horizontal (None where nothing
    faces down)."""
    if boundary.n_elements == 0:
        return None
    u = np.asarray(up, dtype=np.float64)
    u = u / np.linalg.norm(u)
    down = -(element_normals(boundary) @ u)  # sine of the angle below the horizontal
    w = boundary.element_measures()
    keep = np.ones(len(w), dtype=bool) if exempt is None else ~exempt
    facing = keep & (down > 0)
    total = float(w[facing].sum())
    if total <= 0:
        return None
    return float(w[facing & (down > math.sin(math.radians(angle)))].sum()) / total
