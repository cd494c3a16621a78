"""A problem's structural analysis on an element grid: its supports and load cases turned into
the held degrees of freedom and nodal forces of an :class:`~ginn.physics.ElasticitySolver`.

A support or load acts on the grid nodes within half an element (half the longest element side)
of its interfaces or region, on the shape's side of an interface with prescribed normals
(:func:`_nodes`); a load's force is shared equally by its nodes, its torque is a couple
of nodal forces (:func:`couple`). The elements whose
centre lies outside the design region or inside an obstacle are void.

:func:`simp_reference` runs the SIMP optimiser (:func:`ginn.physics.simp`) on the same grid,
the baseline the structural results are measured against.

The material model of the shapes' elements is SIMP's: modulus ``E (VOID + (1 - VOID) rho^PENALTY)``
for a density ``rho`` (the reference optimiser, the training term and the report share it).

Public names: :func:`structural_solver`, :func:`structural_grid`, :func:`couple`, :func:`interface_normals`,
:func:`design_depth`, :func:`void_elements`, :func:`design_shares`,
:func:`held_nodes`, :func:`held_elements`, :func:`held_corners`, :func:`void_at`, :func:`in_obstacles`,
:func:`simp_reference`, :func:`design_on`, :func:`resampled`, :func:`upsample`, :class:`Reference`, :data:`CELLS`, :data:`VOID`,
:data:`PENALTY`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy.ndimage import distance_transform_edt
from scipy.spatial import cKDTree

from ..errors import SpecError
from ..geometry.base import Interface, Region, nearest_interface_points
from ..physics import ElasticitySolver, ElementGrid, SimpResult, simp
from .derived import CELLS, smallest_feature, structural_cells
from .problem import Problem

__all__ = ["structural_solver", "structural_grid", "couple", "interface_normals", "design_depth", "void_elements",
           "design_shares", "held_nodes", "held_elements", "held_corners", "void_at", "in_obstacles",
           "simp_reference", "design_on", "resampled", "upsample", "Reference", "CELLS", "VOID", "PENALTY"]

#: the ersatz material: the modulus of void relative to the solid's
VOID = 1e-6
#: SIMP's penalty exponent: grey elements carry little
PENALTY = 3.0


def structural_grid(problem: Problem, cells: int = 0, smallest: float | None = None) -> ElementGrid:
    """The element grid of ``problem``: ``cells`` elements along the domain's longest side (0: the
    default, :func:`~ginn.problems.derived.structural_cells` for the smallest interface ``smallest``,
    a length), elements as close to squares/cubes as the box allows."""
    d = problem.domain
    if cells <= 0:
        cells = structural_cells(problem, smallest)
    return ElementGrid.over(d.lo, d.hi, cells)


def _near(places: tuple[Interface | Region, ...], x: torch.Tensor, reach: float) -> np.ndarray:
    """``(n,)`` bool: the points ``x`` within ``reach`` of any of the interfaces or inside any of the
    regions grown by ``reach``."""
    near = np.zeros(x.shape[0], bool)
    with torch.no_grad():
        for where in places:
            d = where.distance(x) if isinstance(where, Interface) else where.sdf(x)
            near |= (d <= reach).cpu().numpy()
    return near


def _nodes(places: tuple[Interface | Region, ...], grid: ElementGrid) -> np.ndarray:
    """``(n_nodes,)`` bool: the nodes a support or load on ``places`` acts on: those within half an
    element (half the longest side) of its interfaces or inside its regions grown by as much, each
    node beyond one of its interfaces with prescribed normals (on the side the normals point to,
    within 60 degrees of the normal: inside a bolt hole whose rim is the interface) replaced by its
    neighbour one element along the grid axis nearest the opposite of that normal, on the shape's
    side. A node inside the hole is held only through the elements across the rim, whose centres
    can lie a sliver from it, so a shape whose boundary follows the rim within the interface
    tolerance could leave it on void. A straight face between two node rows keeps its row of nodes
    (the one on the shape's side), where dropping the nodes beyond it would leave it none."""
    x = torch.as_tensor(grid.nodes, dtype=torch.float64)
    reach = 0.5 * float(grid.h.max())
    near = _near(places, x, reach)
    beyond, normal = _void_side([w for w in places if isinstance(w, Interface)], grid.nodes[near], reach)
    if not beyond.any():
        return near
    moved = np.flatnonzero(near)[beyond]
    n = normal[beyond]  # (m, d)
    axis = np.abs(n).argmax(axis=1)
    idx = np.array(np.unravel_index(moved, grid.node_shape))  # (d, m)
    idx[axis, np.arange(moved.size)] -= np.sign(n[np.arange(moved.size), axis]).astype(int)
    ok = np.all((idx >= 0) & (idx < np.asarray(grid.node_shape)[:, None]), axis=0)
    near[moved[ok]] = False  # a node whose neighbour lies past the grid's edge stays
    near[np.ravel_multi_index(tuple(idx[:, ok]), grid.node_shape)] = True
    return near


def _void_side(interfaces: list[Interface], points: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Which ``points`` ``(n, d)`` lie within ``reach`` of one of ``interfaces`` on the side its
    prescribed normals point to (out of the shape: inside a bolt hole whose rim is the interface),
    within 60 degrees of the normal at the point's nearest point on it (a point beside an
    interface's edge is not beyond it): ``(n,)`` bool, and that normal ``(n, d)`` (zeros where not
    beyond), taken from the nearest of a dense sample (spacing about a twentieth of ``reach``; a
    part without normals has no such side)."""
    out = np.zeros(points.shape[0], bool)
    normal = np.zeros(points.shape)
    x = torch.as_tensor(points, dtype=torch.float64)
    for where in interfaces:
        if not where.has_normals or x.shape[0] == 0:
            continue
        with torch.no_grad():
            d, y = where.nearest(x)
        close = (d <= reach).cpu().numpy() & ~out
        if not close.any():
            continue
        spacing = reach / 20.0
        n = int(min(max(where.measure() / spacing ** (where.dim - 1), 1000), 100_000))
        pts, normals = where.sample(n, torch.Generator().manual_seed(0), dtype=torch.float64)
        _, idx = cKDTree(pts.numpy()).query(y[close].numpy())
        nrm = normals.numpy()[idx]
        ahead = ((points[close] - y[close].numpy()) * nrm).sum(axis=1) > 0.5 * d[close].numpy()  # within 60 degrees
        hit = np.flatnonzero(close)[ahead]
        out[hit] = True
        normal[hit] = nrm[ahead]
    return out, normal


def interface_normals(interfaces: tuple[Interface | Region, ...], points: np.ndarray, h: float) -> np.ndarray:
    """``(n, d)`` unit normals of the nearest of ``interfaces`` at the nearest point to each of
    ``points`` ``(n, d)`` (their sign arbitrary): the direction from that nearest point, exact on
    a circle or a line; a point within ``1e-6 h`` of an interface takes it from a probe ``1e-3 h``
    away along the grid axis that leaves the interface fastest."""
    x = torch.as_tensor(points, dtype=torch.float64)
    interfaces = [w for w in interfaces if isinstance(w, Interface)]
    dist, near = nearest_interface_points(interfaces, x)
    v = (x - near).numpy()
    on = np.flatnonzero(dist.numpy() <= 1e-6 * h)
    if on.size:
        best = np.zeros((on.size, v.shape[1]))
        for a in range(v.shape[1]):
            probe = x[on].clone()
            probe[:, a] += 1e-3 * h
            _, y = nearest_interface_points(interfaces, probe)
            va = (probe - y).numpy()
            longer = np.linalg.norm(va, axis=1) > np.linalg.norm(best, axis=1)
            best[longer] = va[longer]
        v[on] = best
    return v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-300)


def couple(x: np.ndarray, torque: tuple[float, ...]) -> np.ndarray:
    """Nodal forces ``(n, d)`` at the points ``x`` ``(n, d)`` that sum to zero and whose moment about
    any point is ``torque`` (``(1,)`` about z in 2D, ``(3,)`` in 3D): each node's force is
    ``omega x r`` (``r`` from the points' centroid), the displacement of a rigid rotation, with
    ``omega`` solving ``J omega = torque`` (``J = sum |r|^2 I - r r^T``, the points' polar inertia).

    Raises:
        ValueError: the points cannot carry the torque (one point, or all on its axis).
    """
    r = x - x.mean(axis=0)
    if x.shape[1] == 2:
        J = float((r**2).sum())
        if J <= 1e-30:
            raise ValueError("one node cannot carry a torque")
        return (torque[0] / J) * np.stack([-r[:, 1], r[:, 0]], axis=1)
    M = np.asarray(torque, float)
    J = (r**2).sum() * np.eye(3) - r.T @ r
    omega = np.linalg.lstsq(J, M, rcond=None)[0]
    if not np.allclose(J @ omega, M, rtol=1e-6, atol=1e-9 * max(np.abs(M).max(), 1e-300)):
        raise ValueError("its nodes lie on the torque's axis and cannot carry it")
    return np.cross(omega, r)


def held_nodes(problem: Problem, grid: ElementGrid) -> np.ndarray:
    """``(n_nodes,)`` bool: the nodes the shape must hold, those of every load and of every
    support placed on interfaces (a support on a region is a wall the shape may meet anywhere)."""
    ph = problem.physics
    if ph is None:
        return np.zeros(grid.n_nodes, bool)
    held = np.zeros(grid.n_nodes, bool)
    places = [s.where for s in ph.supports if all(isinstance(w, Interface) for w in s.where)]
    places += [load.where for case in ph.load_cases for load in case.loads]
    for where in places:
        held |= _nodes(where, grid)
    return held


def held_elements(problem: Problem, grid: ElementGrid) -> np.ndarray:
    """``(n_held, 2^dim)``: for each node of :func:`held_nodes` with an element of E around it, the
    elements of E around it (``-1``: none in that slot). A node is held when one of them is solid."""
    return _held(problem, grid)[1]


def held_corners(problem: Problem, grid: ElementGrid, spacing: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The centres of the elements of side ``spacing`` ``(dim,)`` that have a corner at a node of
    :func:`held_elements` (in its order): points ``(n_held, 2^dim, dim)`` and ``(n_held, 2^dim)``
    bool, whether each lies in E, inside the domain and not beyond a held interface (on the side
    its prescribed normals point to, where the shape must be void: a node of a bolt hole's rim
    inside the hole has its finer elements' centres there when E does not cut the hole out). A
    grid of that spacing with a node there holds the node when one of the present points is
    solid."""
    nodes, _ = _held(problem, grid)
    signs = np.array(np.meshgrid(*[(-1.0, 1.0)] * grid.dim, indexing="ij")).reshape(grid.dim, -1).T  # (2^d, d)
    points = grid.nodes[nodes][:, None, :] + 0.5 * np.asarray(spacing, dtype=np.float64) * signs
    flat = points.reshape(-1, grid.dim)
    inside = np.all((flat > np.asarray(grid.lo)) & (flat < np.asarray(grid.hi)), axis=1) & ~void_at(problem, flat)
    reach = float(np.linalg.norm(spacing)) + float(grid.h.max())  # the farthest corner of a held node
    inside[inside] = ~_void_side(_held_interfaces(problem), flat[inside], reach)[0]
    return points, inside.reshape(points.shape[:2])


def _held_interfaces(problem: Problem) -> list[Interface]:
    """The interfaces of every load and of every support placed on interfaces."""
    ph = problem.physics
    if ph is None:
        return []
    places = [s.where for s in ph.supports if all(isinstance(w, Interface) for w in s.where)]
    places += [load.where for case in ph.load_cases for load in case.loads]
    return [w for where in places for w in where if isinstance(w, Interface)]


def _held(problem: Problem, grid: ElementGrid) -> tuple[np.ndarray, np.ndarray]:
    """The nodes of :func:`held_nodes` with an element of E around them ``(n_held,)`` and those elements."""
    nodes = np.flatnonzero(held_nodes(problem, grid))
    around = grid.node_elements[nodes]
    void = np.append(void_elements(problem, grid), True)  # index -1: past the grid's edge
    around = np.where(void[around], -1, around)
    keep = (around >= 0).any(axis=1)
    return nodes[keep], around[keep]


def void_at(problem: Problem, points: np.ndarray) -> np.ndarray:
    """``(n,)`` bool: which of ``points`` ``(n, dim)`` lie outside E or inside an obstacle."""
    void = in_obstacles(problem, points)
    if problem.design_region is not None:
        with torch.no_grad():
            void |= ~problem.design_region.contains(torch.as_tensor(points, dtype=torch.float64)).cpu().numpy()
    return void


def in_obstacles(problem: Problem, points: np.ndarray) -> np.ndarray:
    """``(n,)`` bool: which of ``points`` ``(n, dim)`` lie inside an obstacle."""
    c = torch.as_tensor(points, dtype=torch.float64)
    inside = np.zeros(c.shape[0], bool)
    with torch.no_grad():
        for o in problem.obstacles:
            inside |= o.contains(c).cpu().numpy()
    return inside


def void_elements(problem: Problem, grid: ElementGrid) -> np.ndarray:
    """``(n_elements,)`` bool: elements whose centre is outside E or inside an obstacle."""
    return void_at(problem, grid.centres)


def design_shares(problem: Problem, grid: ElementGrid) -> np.ndarray:
    """``(n_elements,)``: the share of each element that lies in E, obstacles included (the
    denominator of a volume fraction: ``tolerances.volume_fraction`` bounds
    ``vol(shape ∩ E) / vol(E)``). E's signed distance ``d`` taken as linear across the element, with
    its gradient ``g`` by central differences between the element's faces, ranges over
    ``d(c) +- e / 2``, ``e = sum_a h_a |g_a|``, and the share inside is ``clamp(1/2 - d(c) / e, 0, 1)``,
    the model :func:`ginn.constraints.compliance.covered` applies to the shape: exact for a face
    along a grid axis wherever it cuts the elements, where counting the elements whose centre lies
    in E is off by up to half an element along the whole face (``benchmarks/suite/plate-loads-2d.yaml``
    on its 90 x 50 grid: E's area 1.2 % over its own). Ones without a design region."""
    if problem.design_region is None:
        return np.ones(grid.n_elements)
    c = torch.as_tensor(grid.centres, dtype=torch.float64)
    h = [float(v) for v in grid.h]
    sdf = problem.design_region.sdf
    with torch.no_grad():
        d = sdf(c).to(torch.float64)
        extent = torch.zeros_like(d)
        for a in range(grid.dim):
            step = torch.zeros(grid.dim, dtype=torch.float64)
            step[a] = 0.5 * h[a]
            extent += (sdf(c + step).to(torch.float64) - sdf(c - step).to(torch.float64)).abs()
        share = torch.where(extent > 0, (0.5 - d / extent.clamp_min(1e-300)).clamp(0.0, 1.0), (d <= 0).to(torch.float64))
    return share.cpu().numpy()


def design_depth(problem: Problem, grid: ElementGrid) -> float:
    """How deep the design region is on ``grid``: the largest distance from the centre of an element
    in E to the nearest element outside it or the grid's edge (the radius of the largest ball of
    elements in E; half the short side of a rectangular E)."""
    inside = np.pad(~void_elements(problem, grid).reshape(grid.shape), 1, constant_values=False)
    depth = distance_transform_edt(inside, sampling=[float(h) for h in grid.h])
    return max(float(depth.max()) - 0.5 * float(grid.h.min()), 0.0)


def structural_solver(problem: Problem, grid: ElementGrid, method: str = "auto") -> tuple[ElasticitySolver, np.ndarray]:
    """The solver of ``problem``'s supports and load cases on ``grid`` (its material's Poisson ratio)
    and the load cases' weights ``(L,)``.

    A support with ``normal`` holds its nodes along the normals of :func:`interface_normals` (the
    solver's ``normals``).

    Raises:
        SpecError: a support or a load that reaches no grid node, or a support with ``normal`` on
            interfaces with no distance to take a normal from (naming its spec field).
    """
    ph = problem.physics
    if ph is None:
        raise SpecError(f"problem {problem.name}: no physics block")
    d = grid.dim
    fixed = np.zeros((grid.n_nodes, d), bool)
    normals = np.zeros((grid.n_nodes, d))
    labels, case_labels = ph.labels
    for k, s in enumerate(ph.supports):
        near = _nodes(s.where, grid)
        if not near.any():
            raise SpecError(f"spec field '{labels[k] if labels else 'physics.supports'}': reaches no node of the "
                            f"{'x'.join(map(str, grid.shape))} element grid")
        for a in s.axes:
            fixed[near, a] = True
        if s.normal:
            n = interface_normals(s.where, grid.nodes[near], float(grid.h.min()))
            if not np.all(np.abs(np.linalg.norm(n, axis=1) - 1.0) < 1e-9):
                raise SpecError(f"spec field '{labels[k] if labels else 'physics.supports'}.fix': its interfaces "
                                "have no distance to take a normal from")
            normals[near] = n
    forces = np.zeros((len(ph.load_cases), grid.n_nodes, d))
    for c, case in enumerate(ph.load_cases):
        for j, load in enumerate(case.loads):
            near = _nodes(load.where, grid)
            label = case_labels[c][j] if case_labels else "physics.loads"
            if not near.any():
                raise SpecError(f"spec field '{label}': reaches no node of the {'x'.join(map(str, grid.shape))} element grid")
            forces[c, near] += np.asarray(load.force) / near.sum()
            if load.torque:
                try:
                    forces[c, near] += couple(grid.nodes[near], load.torque)
                except ValueError as e:
                    raise SpecError(f"spec field '{label}.torque': {e}") from None
    # the elements of E, and those at a loaded node (which the CG methods would otherwise leave out)
    loaded = np.flatnonzero(np.abs(forces).sum(axis=(0, 2)) > 0)
    active = ~void_elements(problem, grid)
    around = grid.node_elements[loaded]
    active[around[around >= 0]] = True
    solver = ElasticitySolver(grid, ph.poisson_ratio, fixed.reshape(-1), forces.reshape(len(ph.load_cases), -1),
                              method=method, active=active, normals=normals if normals.any() else None)
    return solver, np.array([case.weight for case in ph.load_cases])


def upsample(values: np.ndarray, shape: tuple[int, ...], factor: int = 2) -> np.ndarray:
    """Per-element ``values`` ``(n_elements,)`` of a grid of ``shape`` on the grid refined ``factor``
    times along each axis (each element's value to its ``factor^dim`` children), in C order."""
    v = np.asarray(values).reshape(shape)
    for axis in range(len(shape)):
        v = np.repeat(v, factor, axis=axis)
    return v.reshape(-1)


@dataclass(frozen=True)
class Reference:
    """The SIMP baseline of a structural problem.

    Attributes:
        result: the SIMP run on the problem's default element grid.
        solid: ``(n_elements,)`` bool, its densest elements up to the volume bound (the design
            thresholded at the bound's volume).
        compliance: the weighted compliance of ``solid`` re-solved on the grid refined twice (void
            modulus 1e-6), as the shapes' report measures them.
    """

    result: SimpResult
    solid: np.ndarray
    compliance: float


def simp_reference(problem: Problem, *, filter_radius: float = 1.5) -> Reference:
    """SIMP (density filter of ``filter_radius`` elements) on ``problem``'s default grid at its volume
    bound (``tolerances.volume_fraction.max``), thresholded at the bound's volume and re-solved on
    the grid refined twice. The elements outside E are held void and those of E around the nodes a
    shape must hold (:func:`held_elements`: the loads and the supports on interfaces) solid, as the
    shapes hold them: a thresholded design that left a loaded node on void would carry its share of
    the load on the void's ersatz modulus."""
    b = problem.tolerances.volume_fraction
    if b is None or b.max is None:
        raise SpecError(f"problem {problem.name}: the SIMP reference needs tolerances.volume_fraction.max")
    grid = structural_grid(problem, 0, smallest_feature(problem))
    solver, w = structural_solver(problem, grid)
    void = void_elements(problem, grid)
    around = held_elements(problem, grid)
    held = np.zeros(grid.n_elements, bool)
    held[around[around >= 0]] = True
    n_solid = int(round(float(b.max) * design_shares(problem, grid).sum()))  # a share of E, obstacles included
    free = max(int((~void & ~held).sum()), 1)  # simp() bounds the density of the elements it moves
    res = simp(solver, max(n_solid - int(held.sum()), 0) / free, penalty=PENALTY, filter_radius=filter_radius,
               weights=w, passive_void=void, passive_solid=held)
    solid = np.zeros(grid.n_elements, bool)
    solid[np.argsort(-np.where(void, -1.0, np.where(held, 2.0, res.density)), kind="stable")[:n_solid]] = True
    fine = grid.refined(2)
    fsolver, _ = structural_solver(problem, fine)
    E = float(problem.physics.youngs_modulus)
    moduli = torch.as_tensor(E * np.where(design_on(problem, solid, grid, fine), 1.0, VOID))
    c = float(w @ fsolver.work(fsolver.solve(moduli))[0].numpy())
    return Reference(res, solid, c)


def resampled(values: np.ndarray, source: ElementGrid, grid: ElementGrid) -> np.ndarray:
    """Per-element ``values`` ``(n_elements,)`` of ``source`` on ``grid``: each element takes the value
    of the ``source`` element under its centre (on a grid that refines ``source``, its parent's)."""
    idx = np.floor((grid.centres - np.asarray(source.lo)) / source.h).astype(int)
    idx = np.clip(idx, 0, np.asarray(source.shape) - 1)
    return np.asarray(values).reshape(source.shape)[tuple(idx.T)]


def design_on(problem: Problem, solid: np.ndarray, grid: ElementGrid, other: ElementGrid) -> np.ndarray:
    """``(n_other,)`` bool: the elements ``solid`` ``(n_elements,)`` of ``grid`` on the ``other``
    grid (each of its elements takes the value of the ``grid`` element under its centre: on a grid
    that refines ``grid``, its children), measured as a shape is there (``ginn eval``): solid only
    in E, and every node of :func:`held_elements` of ``other`` held (its elements of E solid where
    none is). A coarse element whose centre lies in E can leave a fine child outside it, and one
    outside E a child inside it on which a node of a load or support sits: without the second rule
    a load on a pin hole's rim without prescribed normals (on the nodes on both sides of it) was
    left on void (compliance 1579 against 40.2 on the coarse grid, ``tests/test_structural.py``)."""
    out = resampled(np.asarray(solid, bool), grid, other) & ~void_elements(problem, other)
    around = held_elements(problem, other)  # (n_held, 2^d), -1 where no element of E
    held = np.append(out, False)[around].any(axis=1)
    add = around[~held]
    out[add[add >= 0]] = True
    return out
