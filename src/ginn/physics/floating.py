"""The rigid motions of the pieces a design leaves floating: a coarse space the multigrid of
:mod:`ginn.physics.multigrid` cannot represent.

A piece of solid that no chain of solid elements ties to a support hangs in the weak ersatz of
void. Its rigid motions strain only the void around it, so they are eigenvectors of the stiffness
with eigenvalues of the order of the void's modulus, a millionfold below the rest of the spectrum; the
smoother does not reduce them, and a coarse grid does not represent them, because its elements
straddle the piece and the material beside it. CG then needs an iteration for every such mode.

:class:`FloatingModes` finds the pieces of every shape of a batch and spans their rigid motions:

* *solid* are the active elements whose modulus is at least the geometric mean of the shape's
  smallest and largest active moduli (the midpoint of the contrast on a log scale);
* the *pieces* are the components of the solid elements, two elements connected when they share
  a face, less those that hold a fixed degree of freedom: a piece that touches another along an
  edge or at a corner only is a piece of its own, whose hinge motions are as soft;
* the modes of a piece are its ``dim`` translations and ``dim (dim - 1) / 2`` rotations about its
  centroid (the rotations scaled by its RMS radius), on the nodes of its elements: the columns of
  ``Z``. A node shared by two pieces carries the modes of both.

The coarse operator ``A_c = Z^T A Z`` is assembled element by element over the elements with a
corner in a piece (an element of a piece moves rigidly with it and adds nothing to that piece's
own block). :meth:`FloatingModes.correct` applies ``Q = Z A_c^-1 Z^T``; the multigrid balances
its V-cycle ``V`` with it, ``Q + (I - Q A) V (I - A Q)``, which is symmetric positive definite,
exact on the span of ``Z`` and a V-cycle on its ``A``-orthogonal complement.

Public names: :class:`FloatingModes`.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from scipy import ndimage

from .grid import ElementGrid

__all__ = ["FloatingModes"]

CHUNK = 2048  # elements per block of the coarse operator's assembly (bounds its memory)


def _mode_matrices(rel: np.ndarray) -> np.ndarray:
    """``(n, dim, m)``: the rigid modes' displacements at points ``rel`` ``(n, dim)`` (relative to
    the piece's centroid, scaled by its radius): ``dim`` translations, then the rotations."""
    n, d = rel.shape
    if d == 2:
        x, y = rel[:, 0], rel[:, 1]
        one, zero = np.ones(n), np.zeros(n)
        cols = [(one, zero), (zero, one), (-y, x)]
    else:
        x, y, z = rel[:, 0], rel[:, 1], rel[:, 2]
        one, zero = np.ones(n), np.zeros(n)
        cols = [(one, zero, zero), (zero, one, zero), (zero, zero, one), (zero, -z, y), (z, zero, -x), (-y, x, zero)]
    return np.stack([np.stack(c, axis=-1) for c in cols], axis=-1)


class FloatingModes:
    """The floating pieces of a batch of moduli and their rigid motions (module docstring).

    Arguments:
        grid: the element grid.
        K0: ``(k, k)`` the unit-modulus element matrix.
        fixed: ``(n_dofs,)`` bool, the degrees of freedom held at zero.
        moduli: ``(B, n_elements)`` float64, zero at the elements that are not active.
        limit: the most modes a shape keeps (its largest pieces first; None: every piece), so
            that the coarse solve costs no more than the multigrid's coarsest level.

    Attributes:
        n_pieces: ``(B,)`` the floating pieces of each shape (those kept).
        G: the most pieces of a shape of the batch (0: none floats).
    """

    def __init__(self, grid: ElementGrid, K0: np.ndarray, fixed: np.ndarray, moduli: torch.Tensor,
                 limit: int | None = None) -> None:
        d = grid.dim
        self.m = d + d * (d - 1) // 2
        self.dim = d
        dev = moduli.device
        E = moduli.detach().cpu().numpy()
        B = E.shape[0]
        nodes_of = grid.element_nodes  # (ne, 2^d)
        nc = nodes_of.shape[1]
        fixed_node = np.asarray(fixed, dtype=bool).reshape(grid.n_nodes, d).any(axis=1)
        supported = fixed_node[nodes_of].any(axis=1)  # (ne,) the elements with a fixed degree of freedom
        piece_of_element = np.full((B, grid.n_elements), -1, dtype=np.int64)
        counts = np.zeros(B, dtype=np.int64)
        for b in range(B):
            live = E[b] > 0
            if not live.any():
                continue
            lo, hi = float(E[b][live].min()), float(E[b][live].max())
            solid = live & (E[b] >= math.sqrt(lo * hi))
            labels, n = ndimage.label(solid.reshape(grid.shape))  # elements sharing a face
            labels = labels.reshape(-1)
            anchored = np.zeros(n + 1, dtype=bool)
            anchored[labels[solid & supported]] = True
            anchored[0] = True
            index = np.full(n + 1, -1, dtype=np.int64)
            floating = np.flatnonzero(~anchored)
            if limit is not None and floating.size * self.m > limit:
                elements = np.bincount(labels, minlength=n + 1)[floating]
                floating = floating[np.argsort(-elements, kind="stable")[: limit // self.m]]
            index[floating] = np.arange(floating.size)
            counts[b] = floating.size
            piece_of_element[b] = index[labels]
        self.n_pieces = counts
        self.B = B
        self.G = int(counts.max()) if B else 0
        if self.G == 0:
            return
        G, m = self.G, self.m
        # the (shape, node, piece) incidences: a node lies in every piece one of its elements is in
        eb, ee = np.nonzero(piece_of_element >= 0)
        key = np.unique(((eb[:, None] * grid.n_nodes + nodes_of[ee]) * G + piece_of_element[eb, ee][:, None]).reshape(-1))
        piece = key % G
        shape_idx, node_idx = np.divmod(key // G, grid.n_nodes)
        slot = shape_idx * G + piece  # a piece's slot in the batch
        x = grid.nodes[node_idx]
        n_slots = B * G
        size = np.bincount(slot, minlength=n_slots).astype(np.float64)
        centre = np.stack([np.bincount(slot, weights=x[:, a], minlength=n_slots) for a in range(d)], -1)
        centre /= np.maximum(size, 1)[:, None]
        rel = x - centre[slot]
        radius = np.sqrt(np.bincount(slot, weights=(rel**2).sum(1), minlength=n_slots) / np.maximum(size, 1))
        rel = rel / np.maximum(radius[slot], 1e-300)[:, None]
        phi = _mode_matrices(rel)  # (P, d, m)
        # A_c = Z^T A Z element by element: the (element, piece) incidences, each with the modes of
        # its corners in that piece; an element of a piece has every corner in it and is not
        # strained by its rigid motions, so it adds nothing to that piece's own block
        around = grid.node_elements[node_idx]  # (P, nc): the elements at each incidence's node, -1 none
        ok = around >= 0
        ekey = np.unique(((shape_idx[:, None] * grid.n_elements + around) * G + piece[:, None])[ok])
        ip = ekey % G  # (J,) the (element, piece) incidences, sorted by element
        flat = ekey // G  # shape * n_elements + element
        tb, te = np.divmod(flat, grid.n_elements)
        ck = ((tb[:, None] * grid.n_nodes + nodes_of[te]) * G + ip[:, None])  # (J, nc) the corners' keys
        at = np.searchsorted(key, ck).clip(max=key.size - 1)
        hit = key[at] == ck
        W = np.zeros((ekey.size, nc, d, m))  # the modes of the corners in the piece
        W[hit] = phi[at[hit]]
        whole = piece_of_element[tb, te] == ip  # the piece's own elements
        _, first, per = np.unique(flat, return_index=True, return_counts=True)
        K0t = np.asarray(K0, dtype=np.float64).reshape(nc, d, nc, d)
        Ac = np.zeros((B, G, m, G, m))
        for j1 in range(int(per.max())):
            for j2 in range(int(per.max())):
                a, b2 = first + j1, first + j2
                keep = (per > j1) & (per > j2)
                if j1 == j2:
                    keep &= ~whole[np.where(keep, a, 0)]
                a, b2 = a[keep], b2[keep]
                for s0 in range(0, a.size, CHUNK):
                    ia, ib = a[s0: s0 + CHUNK], b2[s0: s0 + CHUNK]
                    blocks = np.einsum("tadi,adbe,tbej->tij", W[ia], K0t, W[ib]) * E[tb[ia], te[ia]][:, None, None]
                    np.add.at(Ac, (tb[ia], ip[ia], slice(None), ip[ib]), blocks)
        n = G * m
        Ac = Ac.reshape(B, n, n)
        unused = np.ones((B, self.G, self.m), dtype=bool)
        for b in range(B):
            unused[b, : counts[b]] = False
        Ac += np.einsum("bi,ij->bij", unused.reshape(B, n).astype(np.float64), np.eye(n))
        Ac = 0.5 * (Ac + np.swapaxes(Ac, 1, 2))
        chol, info = torch.linalg.cholesky_ex(torch.as_tensor(Ac, device=dev))
        if bool((info != 0).any()):  # a mode no active element strains (the operator is singular there too)
            scale = np.abs(np.diagonal(Ac, axis1=1, axis2=2)).max(axis=1)
            Ac += 1e-12 * scale[:, None, None] * np.eye(n)[None]
            chol = torch.linalg.cholesky(torch.as_tensor(Ac, device=dev))
        self.chol = chol
        self.used = torch.as_tensor(~unused.reshape(B, n), device=dev, dtype=torch.float64)
        self.rows = torch.as_tensor(shape_idx, device=dev)
        self.dofs = torch.as_tensor(d * node_idx[:, None] + np.arange(d), device=dev)  # (P, d)
        self.slots = torch.as_tensor(piece, device=dev)
        self.phi = torch.as_tensor(phi, device=dev)

    def correct(self, R: torch.Tensor) -> torch.Tensor:
        """``Z A_c^-1 Z^T R`` for residuals ``R`` ``(B, L, n_dofs)`` (zero where no shape has a
        floating piece)."""
        if self.G == 0:
            return torch.zeros_like(R)
        B, L, n = R.shape
        r = R.transpose(1, 2)[self.rows[:, None], self.dofs]  # (P, d, L)
        zr = torch.einsum("pdm,pdl->pml", self.phi, r)  # (P, m, L)
        c = torch.zeros(B * self.G, self.m, L, dtype=R.dtype, device=R.device)
        c.index_add_(0, self.rows * self.G + self.slots, zr)
        c = c.reshape(B, self.G * self.m, L) * self.used[:, :, None]
        c = torch.cholesky_solve(c, self.chol) * self.used[:, :, None]
        c = c.reshape(B * self.G, self.m, L)[self.rows * self.G + self.slots]  # (P, m, L)
        u = torch.einsum("pdm,pml->pdl", self.phi, c)  # (P, d, L)
        out = torch.zeros(B, n, L, dtype=R.dtype, device=R.device)
        out.index_put_((self.rows[:, None].expand_as(self.dofs), self.dofs), u, accumulate=True)
        return out.transpose(1, 2)

    def basis(self, n_dofs: int) -> torch.Tensor:
        """``Z`` as a dense ``(B, G m, n_dofs)`` tensor (column ``g m + i``: mode ``i`` of piece
        ``g``; zero for the pieces a shape does not have), for checks on small grids."""
        if self.G == 0:
            return torch.zeros(self.B, 0, n_dofs, dtype=torch.float64)
        Z = torch.zeros(self.B, self.G, self.m, n_dofs, dtype=self.phi.dtype, device=self.phi.device)
        rows = self.rows[:, None].expand_as(self.dofs)
        slots = self.slots[:, None].expand_as(self.dofs)
        for i in range(self.m):
            Z[:, :, i].index_put_((rows, slots, self.dofs), self.phi[:, :, i], accumulate=True)
        return Z.reshape(self.B, self.G * self.m, n_dofs)
