"""Betti numbers of a shape sampled on a node grid.

A shape is a boolean node mask (``True``: the node is in the shape). Its nodes are joined across
faces (4-connectivity in 2D, 6 in 3D, as :func:`ginn.extract.grid.label_components` counts
components); its complement is joined across faces, edges and corners (8 / 26), the pairing that
makes the two dual, so that a hole is a complement component the shape encloses:

* ``b0``: the components of the mask;
* 2D: ``b1`` (holes): the complement components that do not touch the grid's border;
* 3D: ``b2`` (cavities): the same, and ``b1`` (tunnels) from the Euler characteristic of the
  mask's cubical complex, ``chi = b0 - b1 + b2`` (:func:`skimage.measure.euler_number`).

The genus of a closed triangle mesh (:func:`mesh_genus`) is the same count read off a surface:
each connected surface of Euler characteristic ``chi_i = V - E + F`` has genus ``(2 - chi_i) / 2``,
and a solid's tunnels are the sum over its boundary surfaces (outer and cavity walls alike).

A hole open to the border of the grid is not a hole: the grid's border closes nothing. Restricted
to the design region (``mask & in_design``), a region cut out of E that the shape surrounds (an
obstacle) is a hole of the shape.

Example::

    betti_numbers(annulus_mask)       # (1, 1)
    betti_numbers(torus_mask)         # (1, 2, 0)
    mesh_genus(torus_vertices, torus_faces)   # 1
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage, sparse
from scipy.sparse import csgraph
from skimage.measure import euler_number

__all__ = ["betti_numbers", "enclosed_components", "mesh_genus"]


def enclosed_components(mask: np.ndarray) -> int:
    """The components of the complement of ``mask`` (full connectivity) that do not touch the
    border of the grid: the holes (2D) or cavities (3D) of the shape."""
    mask = np.asarray(mask, dtype=bool)
    outside = ~mask
    labels, n = ndimage.label(outside, structure=ndimage.generate_binary_structure(mask.ndim, mask.ndim))
    if n == 0:
        return 0
    border = np.zeros(mask.shape, dtype=bool)
    for a in range(mask.ndim):
        idx = [slice(None)] * mask.ndim
        idx[a] = 0
        border[tuple(idx)] = True
        idx[a] = -1
        border[tuple(idx)] = True
    touching = np.unique(labels[border & outside])
    return int(n - np.count_nonzero(touching))


def betti_numbers(mask: np.ndarray) -> tuple[int, ...]:
    """``(b0, b1)`` of a 2D node mask or ``(b0, b1, b2)`` of a 3D one (conventions above).

    Arguments:
        mask: boolean node mask ``(n0, n1)`` or ``(n0, n1, n2)``.
    """
    mask = np.asarray(mask, dtype=bool)
    if mask.ndim not in (2, 3):
        raise ValueError(f"betti_numbers: a 2D or 3D mask, not {mask.ndim}D")
    _, b0 = ndimage.label(mask, structure=ndimage.generate_binary_structure(mask.ndim, 1))
    enclosed = enclosed_components(mask)
    if mask.ndim == 2:
        return int(b0), enclosed
    # pad so that the border does not close anything the Euler characteristic would count
    chi = int(euler_number(np.pad(mask, 1), connectivity=1))
    return int(b0), int(b0) + enclosed - chi, enclosed


def mesh_genus(vertices: np.ndarray, faces: np.ndarray) -> int:
    """The total genus of a closed triangle mesh: ``sum_i (2 - chi_i) / 2 = (2 c - chi) / 2`` over
    its ``c`` connected surfaces, ``chi = V - E + F`` counted over the vertices the faces use.

    Arguments:
        vertices: ``(V, 3)`` (only their number matters; shared vertices must be merged);
        faces: ``(F, 3)`` vertex indices.
    """
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) == 0:
        return 0
    used = np.unique(faces)
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    n = len(vertices)
    n_edges = len(np.unique(edges[:, 0] * n + edges[:, 1]))
    chi = len(used) - n_edges + len(faces)
    adjacency = sparse.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    _, labels = csgraph.connected_components(adjacency, directed=False)
    surfaces = len(np.unique(labels[used]))
    return (2 * surfaces - chi) // 2
