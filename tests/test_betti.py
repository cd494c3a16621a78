"""Betti numbers of node masks: analytic shapes with known topology, and agreement with cubical
persistent homology (cripser, V-construction) on random shapes."""

import numpy as np
import pytest
from scipy import ndimage

from ginn.topology.betti import betti_numbers, enclosed_components


def _grid(n: int, dim: int) -> list[np.ndarray]:
    ax = np.linspace(-1.0, 1.0, n)
    return np.meshgrid(*([ax] * dim), indexing="ij")


def test_2d_shapes_of_known_topology():
    x, y = _grid(129, 2)
    r = np.hypot(x, y)
    annulus = (r <= 0.7) & (r >= 0.3)
    assert betti_numbers(annulus) == (1, 1)
    two_disks = (np.hypot(x + 0.5, y) <= 0.3) | (np.hypot(x - 0.5, y) <= 0.3)
    assert betti_numbers(two_disks) == (2, 0)
    two_holes = (r <= 0.9) & (np.hypot(x + 0.4, y) > 0.2) & (np.hypot(x - 0.4, y) > 0.2)
    assert betti_numbers(two_holes) == (1, 2)
    c_shape = annulus & ~((np.abs(y) < 0.1) & (x > 0))  # the ring cut open
    assert betti_numbers(c_shape) == (1, 0)
    # a ring around a hole that opens onto the grid's border encloses nothing
    assert betti_numbers((np.hypot(x - 1.0, y) <= 0.7) & (np.hypot(x - 1.0, y) >= 0.3)) == (1, 0)
    # the empty and the full grid
    assert betti_numbers(np.zeros_like(x, dtype=bool)) == (0, 0)
    assert betti_numbers(np.ones_like(x, dtype=bool)) == (1, 0)


def test_diagonal_neighbours_join_the_complement_not_the_shape():
    # two nodes touching at a corner are two components, and the nodes they fence off diagonally
    # are not a hole (the complement is joined across corners)
    m = np.zeros((6, 6), dtype=bool)
    m[2, 2] = m[3, 3] = True
    assert betti_numbers(m) == (2, 0)
    ring = np.zeros((7, 7), dtype=bool)
    ring[2:5, 2:5] = True
    ring[3, 3] = False
    assert betti_numbers(ring) == (1, 1)


def test_3d_solids_of_known_topology():
    x, y, z = _grid(65, 3)
    r = np.sqrt(x**2 + y**2 + z**2)
    assert betti_numbers(r <= 0.6) == (1, 0, 0)  # ball
    assert betti_numbers((r <= 0.8) & (r >= 0.4)) == (1, 0, 1)  # spherical shell: one cavity
    rho = np.hypot(x, y)
    torus = (rho - 0.55) ** 2 + z**2 <= 0.2**2  # a solid torus: one tunnel
    assert betti_numbers(torus) == (1, 1, 0)
    left = (np.hypot(x + 0.4, y) - 0.3) ** 2 + z**2 <= 0.12**2
    right = (np.hypot(x - 0.4, y) - 0.3) ** 2 + z**2 <= 0.12**2
    assert betti_numbers(left | right) == (1, 2, 0)  # two tori joined: two tunnels
    assert betti_numbers((r <= 0.3) | (np.sqrt((x - 0.7) ** 2 + y**2 + z**2) <= 0.2)) == (2, 0, 0)
    assert enclosed_components((r <= 0.8) & (r >= 0.4)) == 1


@pytest.mark.parametrize("dim, n, seed", [(2, 48, 0), (2, 48, 1), (3, 20, 0), (3, 20, 1)])
def test_agrees_with_cubical_persistent_homology(dim, n, seed):
    cripser = pytest.importorskip("cripser")
    rng = np.random.default_rng(seed)
    field = ndimage.gaussian_filter(rng.standard_normal((n,) * dim), 1.5)
    mask = field <= np.quantile(field, 0.5)
    ph = np.asarray(cripser.computePH(np.where(mask, -1.0, 1.0), maxdim=dim - 1))
    alive = (ph[:, 1] <= 0) & (ph[:, 2] > 0)
    expected = tuple(int(np.count_nonzero(alive & (ph[:, 0] == k))) for k in range(dim))
    got = betti_numbers(mask)
    assert got[:dim] == expected and sum(got) > 2  # a shape with some topology


def test_mesh_genus_of_extracted_surfaces_matches_the_tunnels():
    from ginn.extract.boundary import extract_boundary
    from ginn.extract.export import watertight_mesh
    from ginn.extract.grid import make_grid
    from ginn.geometry.base import Box
    from ginn.topology.betti import mesh_genus

    grid = make_grid(Box((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0)), 48)
    x, y, z = (grid.points().reshape(*grid.shape, 3)[..., i] for i in range(3))
    r = np.sqrt(x**2 + y**2 + z**2)
    torus = np.sqrt((np.hypot(x, y) - 0.55) ** 2 + z**2) - 0.2
    left = np.sqrt((np.hypot(x + 0.4, y) - 0.3) ** 2 + z**2) - 0.12
    right = np.sqrt((np.hypot(x - 0.4, y) - 0.3) ** 2 + z**2) - 0.12
    shell = np.abs(r - 0.6) - 0.2
    apart = np.minimum(torus, np.sqrt((x - 0.0) ** 2 + y**2 + z**2) - 0.15)  # a torus and a ball in its hole
    for values, genus in ((r - 0.6, 0), (torus, 1), (np.minimum(left, right), 2), (shell, 0), (apart, 1)):
        mesh = watertight_mesh(extract_boundary(values, grid, close=True))
        assert mesh.is_watertight
        assert mesh_genus(mesh.vertices, mesh.faces) == genus
        assert mesh_genus(mesh.vertices, mesh.faces) == betti_numbers(values <= 0)[1]
    assert mesh_genus(np.zeros((0, 3)), np.zeros((0, 3), np.int64)) == 0
