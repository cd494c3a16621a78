"""Element matrices of linear elasticity on a structured grid: bilinear quadrilaterals (plane
stress, unit thickness) in 2D, trilinear hexahedra in 3D, for a unit Young's modulus.

Local numbering: corner ``c`` of an element sits at the offset whose bit ``k`` is ``(c >> k) & 1``
along axis ``k`` (2D: (0,0) (1,0) (0,1) (1,1)); an element's degrees of freedom are its corners'
displacement components, corner-major (``u_x, u_y[, u_z]`` of corner 0, then corner 1, ...).
Strains and stresses are in Voigt order: 2D ``(xx, yy, 2 xy)``; 3D ``(xx, yy, zz, 2 yz, 2 xz, 2 xy)``.
Everything is float64 NumPy; the matrices are integrated exactly (2 Gauss points per axis).

Public names: :func:`elasticity_matrix`, :func:`corner_offsets`, :func:`strain_matrix`,
:func:`element_stiffness`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["elasticity_matrix", "corner_offsets", "strain_matrix", "element_stiffness"]


def elasticity_matrix(dim: int, nu: float) -> np.ndarray:
    """The isotropic elasticity matrix ``D`` for Young's modulus 1 and Poisson's ratio ``nu``:
    ``(3, 3)`` plane stress in 2D, ``(6, 6)`` in 3D (Voigt order, engineering shear strains)."""
    if dim == 2:
        return np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, 0.5 * (1.0 - nu)]]) / (1.0 - nu * nu)
    lam = nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    mu = 0.5 / (1.0 + nu)
    D = np.zeros((6, 6))
    D[:3, :3] = lam
    D[np.arange(3), np.arange(3)] += 2.0 * mu
    D[np.arange(3, 6), np.arange(3, 6)] = mu
    return D


def corner_offsets(dim: int) -> np.ndarray:
    """``(2^dim, dim)`` integer offsets of an element's corners in the local numbering."""
    c = np.arange(2**dim)
    return (c[:, None] >> np.arange(dim)[None, :]) & 1


def strain_matrix(h: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """The strain-displacement matrix ``B`` at local points ``xi`` of an element of sides ``h``.

    Arguments:
        h: ``(dim,)`` element side lengths.
        xi: ``(q, dim)`` local coordinates in ``[0, 1]^dim``.
    Returns:
        ``(q, 3, 8)`` in 2D, ``(q, 6, 24)`` in 3D: ``eps = B u_e``.
    """
    h = np.asarray(h, dtype=np.float64)
    dim = h.shape[0]
    xi = np.atleast_2d(np.asarray(xi, dtype=np.float64))
    off = corner_offsets(dim)  # (n, d)
    # shape function of corner c: prod_k (off_ck xi_k + (1 - off_ck)(1 - xi_k)); its derivative along axis k
    lin = np.where(off[None], xi[:, None, :], 1.0 - xi[:, None, :])  # (q, n, d)
    sign = np.where(off == 1, 1.0, -1.0)  # (n, d)
    grad = np.empty(lin.shape)
    for k in range(dim):
        others = np.prod(np.delete(lin, k, axis=2), axis=2)
        grad[:, :, k] = sign[None, :, k] * others / h[k]
    q, n = grad.shape[:2]
    nv = 3 if dim == 2 else 6
    B = np.zeros((q, nv, n * dim))
    shear = [(0, 1)] if dim == 2 else [(1, 2), (0, 2), (0, 1)]
    for k in range(dim):
        B[:, k, k::dim] = grad[:, :, k]
    for s, (a, b) in enumerate(shear):
        B[:, dim + s, a::dim] = grad[:, :, b]
        B[:, dim + s, b::dim] = grad[:, :, a]
    return B


def _gauss(dim: int) -> tuple[np.ndarray, np.ndarray]:
    """2-point Gauss rule per axis on ``[0, 1]^dim``: points ``(2^dim, dim)``, weights ``(2^dim,)``."""
    g = 0.5 + np.array([-1.0, 1.0]) / (2.0 * np.sqrt(3.0))
    pts = g[corner_offsets(dim)]
    return pts, np.full(2**dim, 0.5**dim)


def element_stiffness(h, nu: float) -> np.ndarray:
    """The stiffness matrix of one element of sides ``h`` (``(dim,)``) for Young's modulus 1:
    ``(8, 8)`` in 2D (plane stress, unit thickness), ``(24, 24)`` in 3D. ``u_e^T K0 u_e`` is twice the
    element's strain energy."""
    h = np.asarray(h, dtype=np.float64)
    dim = h.shape[0]
    pts, w = _gauss(dim)
    B = strain_matrix(h, pts)
    D = elasticity_matrix(dim, nu)
    K = np.einsum("q,qia,ij,qjb->ab", w, B, D, B) * float(np.prod(h))
    return 0.5 * (K + K.T)
