"""The structural solver and the SIMP reference (``docs/structural.md``).

    python benchmarks/structural.py simp        # the half MBB beam, 60 x 20, against the 88-line code
    python benchmarks/structural.py solver      # direct vs CG, batched vs one by one (ratios, interleaved)
    python benchmarks/structural.py factorisers # the last part of solver alone: the 2D factorisers
    python benchmarks/structural.py multigrid   # the bracket's four load cases: CG's preconditioners
    python benchmarks/structural.py direct      # the same by the direct method (PARDISO)
    python benchmarks/structural.py mbb RUN     # a run of a structural problem against SIMP on the same problem
    python benchmarks/structural.py grids RUN   # the run's exported shapes and SIMP's design re-solved on other grids

``simp`` runs :func:`ginn.physics.simp` on the half MBB beam of Sigmund (2001) and Andreassen et al.
(2011): 60 x 20 unit elements, the left edge on rollers (the symmetry line), the lower right corner
on a roller, a unit load down at the upper left corner, E = 1, nu = 0.3, E_min = 1e-9, volume
fraction 0.5, penalty 3, both filters at radius 1.5 and 2.4. It prints the compliance of the last
iteration (what the 88-line code prints), the compliance of the final design, the iterations, the
volume fraction and the seconds.

``solver`` times solves of one grey-free solid/void design (void modulus 1e-6) with each method on
2D and 3D grids, a batch of 8 shapes solved by CG in one call against the same 8 one by one, and
the 2D direct method's factoriser (LAPACK's band Cholesky called without the interpreter lock,
the shapes side by side on torch's threads, each on one BLAS thread) on the 16 shapes of a 90 x 60
batch against SciPy's SuperLU and
QDLDL (``pip install qdldl``: the sparse ``L D L^T`` with an approximate-minimum-degree ordering,
its symbolic analysis reused; where it is installed, also one matrix on one thread from 90 x 30
to 360 x 240 elements), both on torch's threads, and (with more than one torch thread) against
the same band through ``scipy.linalg.lapack``'s wrappers side by side (they hold the interpreter
lock) and the band's shapes one after another on one BLAS thread and on as many BLAS threads as
torch's;
the configurations take turns block by block and the script prints medians and ratios.
``factorisers`` runs that last comparison alone (on torch's default thread count).

``multigrid`` solves the ``bracket-loads`` problem's four load cases for 4 shapes on its training
grid (derived from its smallest interface, as ``ginn train`` derives it), each design E's elements
at densities ``rho`` in ``(0.1, 0.5)`` varying across the envelope, moduli ``VOID + rho^p``:
``p = 1`` (the grey start of a run) and ``p = 3`` with ``rho`` thresholded at 0.3 (a solid/void end),
cold (from zero) and warm (from the solve of the same designs' moduli 1 % lower: a step of a run),
by CG with the multigrid V-cycle (balanced by the floating pieces' rigid motions, the code's),
with the plain V-cycle and with the diagonal, taking turns; it prints each design's floating
pieces per shape, the seconds, the iterations and their ratios.

``direct`` solves the same designs by the direct method (PARDISO where the ``pardiso`` extra is
installed, SuperLU otherwise: one factorisation per shape for its four load cases, the shapes side
by side on torch's threads): the first solve (ordering, symbolic analysis and the factors' memory
included) and the median of the next ``--blocks`` ones.

``mbb RUN`` (any structural problem's run, after ``ginn eval RUN``) prints the run's volume
fractions and compliances from its ``metrics.json`` beside the SIMP reference of its problem
(:func:`ginn.problems.structural.simp_reference`) and their ratio.

``grids RUN`` (a 2D structural run, after ``ginn train``, which exports the shapes) reads the
shapes' exported contours (``shapes/shape*.json``), not the network, fills each grid's elements whose
centre lies inside them (even-odd: outlines and holes), and solves every shape and the SIMP
reference's thresholded design (each grid element takes the value of the default-grid element
under its centre) on grids of ``--cells`` elements along the longest side, nested in the default
grid or not. It prints, per grid, SIMP's compliance, the shapes' compliances, their ratios to SIMP's,
their volume fractions and how many leave a node of a load or interface support on void: whether
the report's numbers hold on grids other than its own.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from pathlib import Path

import numpy as np
import scipy.sparse.linalg as spla
import torch
from skimage.draw import polygon

from ginn.physics import ElasticitySolver, ElementGrid, FloatingModes, Multigrid, simp
from ginn.physics.pardiso import available as pardiso_available
from ginn.problems import load_spec
from ginn.problems.derived import smallest_feature
from ginn.problems.structural import (
    VOID,
    design_on,
    design_shares,
    held_elements,
    simp_reference,
    structural_grid,
    structural_solver,
    void_elements,
)

PUBLISHED = {("sensitivity", 2.4): 216.81, ("density", 2.4): 233.71}


def mbb(nx: int = 60, ny: int = 20, method: str = "direct") -> ElasticitySolver:
    g = ElementGrid((0.0, 0.0), (float(nx), float(ny)), (nx, ny))
    x = g.nodes
    fixed = np.zeros((g.n_nodes, 2), bool)
    fixed[np.isclose(x[:, 0], 0), 0] = True
    fixed[np.isclose(x[:, 0], nx) & np.isclose(x[:, 1], 0), 1] = True
    F = np.zeros((g.n_nodes, 2))
    F[np.isclose(x[:, 0], 0) & np.isclose(x[:, 1], ny), 1] = -1.0
    return ElasticitySolver(g, 0.3, fixed.reshape(-1), F.reshape(1, -1), method=method)


def run_simp() -> None:
    print("| filter | radius | compliance (last iteration) | published | final design | iterations | volume | seconds |")
    print("|---|---|---|---|---|---|---|---|")
    for filt in ("sensitivity", "density"):
        for radius in (1.5, 2.4):
            t = time.perf_counter()
            r = simp(mbb(), 0.5, penalty=3.0, filter_radius=radius, filter=filt)
            pub = PUBLISHED.get((filt, radius))
            print(f"| {filt} | {radius} | {r.history[-1]:.2f} | {pub if pub else '–'} | {r.compliance:.2f} | "
                  f"{r.iterations} | {r.volume_fraction:.4f} | {time.perf_counter() - t:.1f} |")


def cantilever_case(shape: tuple[int, ...], method: str) -> tuple[ElasticitySolver, torch.Tensor]:
    d = len(shape)
    g = ElementGrid((0.0,) * d, (3.0, 1.0, 1.0)[:d], shape)
    x = g.nodes
    fixed = np.zeros((g.n_nodes, d), bool)
    fixed[np.isclose(x[:, 0], 0)] = True
    F = np.zeros((g.n_nodes, d))
    end = np.isclose(x[:, 0], 3.0)
    F[end, 1] = -1.0 / end.sum()
    c = g.centres
    solid = (np.abs(c[:, 1] - 0.5) < 0.1) | (np.abs(c[:, 1] - c[:, 0] / 3) < 0.05) | (c[:, 0] < 0.2)
    E = torch.tensor(np.where(solid, 1.0, 1e-6))
    return ElasticitySolver(g, 0.3, fixed.reshape(-1), F.reshape(1, -1), method=method, rtol=1e-8), E


def run_solver(blocks: int) -> None:
    torch.set_num_threads(max(1, torch.get_num_threads()))
    for shape in ((120, 40), (240, 80), (24, 12, 12), (40, 20, 20)):
        cases = {m: cantilever_case(shape, m) for m in ("direct", "cg", "cg-diagonal")}
        times: dict[str, list[float]] = {m: [] for m in cases}
        its: dict[str, int] = {}
        for _ in range(blocks):
            for m, (s, E) in cases.items():
                s._warm.clear()  # a cold solve each time
                t = time.perf_counter()
                s.solve(E)
                times[m].append(time.perf_counter() - t)
                its[m] = s.iterations if m != "direct" else 0
        med = {m: statistics.median(v) for m, v in times.items()}
        n = cases["cg"][0].free.size
        print(f"{shape}: {n} unknowns; direct {med['direct']:.3f} s, cg {med['cg']:.3f} s ({its['cg']} iterations), "
              f"cg-diagonal {med['cg-diagonal']:.3f} s ({its['cg-diagonal']} iterations); cg / direct "
              f"{med['cg'] / med['direct']:.2f}, cg-diagonal / cg {med['cg-diagonal'] / med['cg']:.2f}")
    for shape in ((120, 40), (24, 12, 12)):
        s, E = cantilever_case(shape, "cg")
        batch = torch.stack([E * (1 + 0.1 * k) for k in range(8)])
        one, many = [], []
        for _ in range(blocks):
            s._warm.clear()
            t = time.perf_counter()
            s.solve(batch)
            many.append(time.perf_counter() - t)
            t = time.perf_counter()
            for k in range(8):
                s._warm.clear()
                s.solve(batch[k])
            one.append(time.perf_counter() - t)
        print(f"{shape} CG, 8 shapes: batched {statistics.median(many):.3f} s, one by one {statistics.median(one):.3f} s, "
              f"one by one / batched {statistics.median(one) / statistics.median(many):.2f}")
    band_sizes(blocks)
    factorisers(blocks)


def bracket_designs():
    """``(problem, grid, void, designs)``: the ``bracket-loads`` problem on its training grid and
    the ``multigrid`` comparison's two designs of 4 shapes (``{name: (4, n_elements) moduli}``)."""
    from ginn.problems.derived import smallest_feature
    from ginn.problems.loader import get_spec

    problem = get_spec("bracket-loads").build()
    grid = structural_grid(problem, 0, smallest_feature(problem))
    void = void_elements(problem, grid)
    c = grid.centres
    rho = np.stack([0.3 + 0.2 * np.sin(7 * c[:, 0] + b) * np.cos(5 * c[:, 1]) * np.sin(6 * c[:, 2] + b) for b in range(4)])
    designs = {"grey, p = 1": VOID + rho, "solid/void, p = 3": VOID + np.where(rho > 0.3, 1.0, 0.0)}
    return problem, grid, void, designs


def run_direct(blocks: int) -> None:
    """The ``direct`` timing of the module docstring."""
    problem, grid, void, designs = bracket_designs()
    direct = structural_solver(problem, grid, "direct")[0]
    kind = "PARDISO" if pardiso_available() else "SuperLU"
    print(f"bracket-loads, direct ({kind}): 4 shapes x {direct.n_loads} load cases, {direct.free.size} unknowns, "
          f"{torch.get_num_threads()} thread(s)")
    for name, d in designs.items():
        E = torch.as_tensor(np.where(void, VOID, d))
        t0 = time.perf_counter()
        direct.solve(E)
        first = time.perf_counter() - t0
        times = []
        for _ in range(blocks):
            t0 = time.perf_counter()
            direct.solve(E)
            times.append(time.perf_counter() - t0)
        print(f"  {name}: first solve {first:.2f} s, then {statistics.median(times):.2f} s (median of {blocks})", flush=True)


def run_multigrid(blocks: int) -> None:
    """The ``multigrid`` comparison of the module docstring."""
    problem, grid, void, designs = bracket_designs()
    solvers = {m: structural_solver(problem, grid, "cg" if m == "plain" else m)[0] for m in ("cg", "plain", "cg-diagonal")}
    plain = solvers["plain"]
    plain._mg = Multigrid(grid, plain.K0, plain.held, plain.active, floating=False)
    print(f"bracket-loads on {'x'.join(map(str, grid.shape))} elements ({grid.n_dofs} degrees of freedom, "
          f"{int((~void).sum())} of {grid.n_elements} elements in E), 4 shapes x {solvers['cg'].n_loads} load cases, "
          f"{torch.get_num_threads()} thread(s)")
    print("| design | floating pieces | start | multigrid | without the pieces' modes | diagonal | without / multigrid "
          "| diagonal / multigrid |")
    print("|---|---|---|---|---|---|---|---|")
    for name, d in designs.items():
        E = torch.as_tensor(np.where(void, VOID, d))
        pieces = FloatingModes(grid, plain.K0, plain.held, torch.where(torch.as_tensor(plain.active), E, 0.0)).n_pieces
        for start in ("cold", "warm"):
            t: dict[str, list[float]] = {m: [] for m in solvers}
            its: dict[str, int] = {}
            for _ in range(blocks):
                for m, s in solvers.items():
                    s._warm.clear()
                    if start == "warm":
                        s.solve(0.99 * E)
                    t0 = time.perf_counter()
                    s.solve(E)
                    t[m].append(time.perf_counter() - t0)
                    its[m] = s.iterations
            med = {m: statistics.median(v) for m, v in t.items()}
            print(f"| {name} | {', '.join(map(str, pieces))} | {start} | {med['cg']:.2f} s ({its['cg']} iterations) | "
                  f"{med['plain']:.2f} s ({its['plain']} iterations) | {med['cg-diagonal']:.2f} s "
                  f"({its['cg-diagonal']} iterations) | {med['plain'] / med['cg']:.1f} | {med['cg-diagonal'] / med['cg']:.1f} |",
                  flush=True)


def band_sizes(blocks: int) -> None:
    """One 2D matrix's direct solve (the band) against QDLDL's (its symbolic analysis reused, one
    refinement step; where installed) from 90 x 30 to 360 x 240 elements, on one thread."""
    try:
        import qdldl
    except ImportError:
        return
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    for shape in ((90, 30), (90, 60), (180, 120), (360, 240)):
        s, E = cantilever_case(shape, "direct")
        En = E.numpy()
        f = s.forces[0, s.free]
        ldl = qdldl.Solver(s.stiffness(En).tocsc())

        def by_qdldl() -> np.ndarray:
            K = s.stiffness(En)
            ldl.update(K.tocsc())
            u = ldl.solve(f)
            return u + ldl.solve(f - K @ u)

        runs = {"band": lambda: s.solve(E), "QDLDL": by_qdldl}
        timed: dict[str, list[float]] = {k: [] for k in runs}
        for _ in range(blocks):
            for k, fn in runs.items():
                t = time.perf_counter()
                fn()
                timed[k].append(time.perf_counter() - t)
        med = {k: statistics.median(v) for k, v in timed.items()}
        print(f"{shape} one matrix, one thread: {s.free.size} unknowns, half-bandwidth {s.band_layout()[3]}; band {med['band']:.4f} s, "
              f"QDLDL {med['QDLDL']:.4f} s, QDLDL / band {med['QDLDL'] / med['band']:.2f}")
    torch.set_num_threads(threads)


def factorisers(blocks: int) -> None:
    """The 2D direct method's factoriser (``ElasticitySolver``: LAPACK's band Cholesky called
    without the interpreter lock, the shapes side by side on torch's threads on one BLAS thread
    each, one refinement step) against SuperLU and QDLDL (on torch's threads, QDLDL where
    installed), against the same band through ``scipy.linalg.lapack`` (which holds the lock) side
    by side, and against the band's shapes one after another, for the 16 shapes of a 90 x 60
    batch."""
    from scipy.linalg import lapack
    from threadpoolctl import ThreadpoolController

    s, E = cantilever_case((90, 60), "direct")
    batch = torch.stack([E * (1 + 0.1 * k) for k in range(16)])
    F = np.ascontiguousarray(s.forces[:, s.free].T)
    threads = torch.get_num_threads()
    order, slots, upper, w = s.band_layout()
    blas = ThreadpoolController()

    def superlu(b: int) -> np.ndarray:
        return spla.splu(s.stiffness(batch[b].numpy()).tocsc(), permc_spec="MMD_AT_PLUS_A").solve(F)

    def band(b: int) -> np.ndarray:  # the solver's steps through SciPy's wrappers
        K = s.stiffness(batch[b].numpy())
        ab = np.zeros((w + 1, order.size), order="F")
        ab.reshape(-1, order="F")[slots] = K.data[upper]
        cf, _ = lapack.dpbtrf(ab, lower=0, overwrite_ab=1)
        x = np.empty_like(F)
        x[order] = lapack.dpbtrs(cf, F[order], lower=0)[0]
        x[order] += lapack.dpbtrs(cf, (F - K @ x)[order], lower=0)[0]
        return x

    def band_in_turn(blas_threads: int) -> list:
        with blas.limit(limits=blas_threads, user_api="blas"):
            return [band(b) for b in range(16)]

    def band_side_by_side() -> list:  # SciPy's wrappers, which hold the interpreter lock
        with blas.limit(limits=1, user_api="blas"):
            return list(pool.map(band, range(16)))

    runs = {"band": lambda: s.solve(batch), "SuperLU": lambda: list(pool.map(superlu, range(16)))}
    try:
        import qdldl
    except ImportError:
        print("(QDLDL is not installed: pip install qdldl to time it)")
    else:
        chunks = np.array_split(np.arange(16), threads)
        ldl: dict[int, qdldl.Solver] = {}

        def qdldl_chunk(k: int) -> None:  # chunk k of the shapes with QDLDL solver k (its symbolic analysis reused)
            for b in chunks[k]:
                K = s.stiffness(batch[b].numpy())
                if k not in ldl:
                    ldl[k] = qdldl.Solver(K.tocsc())
                else:
                    ldl[k].update(K.tocsc())
                u = ldl[k].solve(F[:, 0])
                u + ldl[k].solve(F[:, 0] - K @ u)

        runs["QDLDL"] = lambda: list(pool.map(qdldl_chunk, range(threads)))
    if threads > 1:
        runs["band through scipy.linalg.lapack, side by side"] = band_side_by_side
        runs["band, one shape after another"] = partial(band_in_turn, 1)
        runs[f"band, one shape after another on {threads} BLAS threads"] = partial(band_in_turn, threads)
    timed: dict[str, list[float]] = {k: [] for k in runs}
    with ThreadPoolExecutor(threads) as pool:
        for _ in range(blocks):
            for k, fn in runs.items():
                t = time.perf_counter()
                fn()
                timed[k].append(time.perf_counter() - t)
        U = s.solve(batch)[:, 0][:, s.free].numpy()
        ref = np.stack([superlu(b)[:, 0] for b in range(16)])
    med = {k: statistics.median(v) for k, v in timed.items()}
    print(f"(90, 60) direct, 16 shapes, {threads} torch thread(s), half-bandwidth {w}: "
          + ", ".join(f"{k} {v:.3f} s ({v / med['band']:.2f} x band)" for k, v in med.items())
          + f"; band against SuperLU: largest difference {np.abs(U - ref).max() / np.abs(ref).max():.1e}")


def run_against_simp(run: Path) -> None:
    metrics = json.loads((run / "metrics.json").read_text())
    problem = load_spec(run / "problem.yaml").build()
    t = time.perf_counter()
    ref = simp_reference(problem)
    e_volume = design_shares(problem, structural_grid(problem, 0, smallest_feature(problem))).sum()
    print(f"SIMP reference: volume fraction {ref.solid.sum() / e_volume:.3f} of E, compliance {ref.compliance:.4g} "
          f"({ref.result.iterations} iterations, {time.perf_counter() - t:.1f} s)")
    for k, shape in enumerate(metrics["shapes"]):
        c = shape.get("compliance")
        print(f"shape {k}: volume fraction {shape.get('volume_fraction'):.3f}, compliance {c:.4g}, "
              f"/ SIMP {c / ref.compliance:.3f}")


def contour_mask(contours: list[np.ndarray], grid: ElementGrid) -> np.ndarray:
    """``(n_elements,)`` bool: the elements of a 2D ``grid`` whose centre lies inside the shape that the
    closed polylines ``contours`` (each ``(n, 2)``) bound, by the even-odd rule (an outline and its holes)."""
    if grid.dim != 2:
        raise ValueError("contour_mask: a 2D grid")
    lo, h = np.asarray(grid.lo, float), grid.h
    inside = np.zeros(grid.shape, bool)
    for c in contours:
        c = np.asarray(c, float)
        # element (i, j) has its centre at lo + (i + 1/2, j + 1/2) h: pixel (i, j) in skimage's terms
        i, j = polygon((c[:, 0] - lo[0]) / h[0] - 0.5, (c[:, 1] - lo[1]) / h[1] - 0.5, grid.shape)
        inside[i, j] ^= True
    return inside.reshape(-1)


def run_on_grids(run: Path, cells: list[int]) -> None:
    files = sorted((run / "shapes").glob("shape*.json"))
    if not (run / "problem.yaml").is_file() or not files:
        print(f"{run}: needs a run directory with problem.yaml and exported shapes (shapes/shape*.json)", file=sys.stderr)
        raise SystemExit(2)
    problem = load_spec(run / "problem.yaml").build()
    if problem.dim != 2 or problem.physics is None:
        print(f"{run}: needs a 2D structural run (problem {problem.name})", file=sys.stderr)
        raise SystemExit(2)
    shapes = [[np.asarray(c) for c in json.loads(f.read_text())["contours"]] for f in files]
    ref = simp_reference(problem)
    smallest = smallest_feature(problem)
    base = structural_grid(problem, 0, smallest)
    report = [s.get("compliance") for s in json.loads((run / "metrics.json").read_text())["shapes"]] \
        if (run / "metrics.json").exists() else []
    print(f"{len(shapes)} shapes from {run / 'shapes'}; default grid {'x'.join(map(str, base.shape))}")
    if report:
        print(f"the report (ginn eval, {'x'.join(map(str, base.refined(2).shape))} from the field): "
              f"{min(report):.1f} to {max(report):.1f} (mean {np.mean(report):.1f})")
    print("| grid | SIMP | shapes | / SIMP | volume fractions | shapes with a load or interface support node on void | seconds |")
    print("|---|---|---|---|---|---|---|")
    E = float(problem.physics.youngs_modulus)
    for n in cells:
        t = time.perf_counter()
        grid = structural_grid(problem, n, smallest)
        solver, w = structural_solver(problem, grid)
        void = void_elements(problem, grid)
        solid = np.stack([design_on(problem, ref.solid, base, grid)] + [contour_mask(c, grid) & ~void for c in shapes])
        U = solver.solve(torch.as_tensor(E * np.where(solid, 1.0, VOID)))
        c = solver.work(U).numpy() @ w
        vol = solid[:, ~void].mean(axis=1)
        around = held_elements(problem, grid)  # (n_held, 2^d), -1: no element of E in the slot
        unheld = ~(np.append(solid, np.zeros((len(solid), 1), bool), axis=1)[:, around]).any(axis=2).all(axis=1)
        r = c[1:] / c[0]
        print(f"| {'x'.join(map(str, grid.shape))} | {c[0]:.1f} (volume {vol[0]:.3f}) | {c[1:].min():.1f} to "
              f"{c[1:].max():.1f} (mean {c[1:].mean():.1f}) | {r.min():.3f} to {r.max():.3f} (mean {r.mean():.3f}) | "
              f"{vol[1:].min():.4f} to {vol[1:].max():.4f} | {int(unheld[1:].sum())} | {time.perf_counter() - t:.0f} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", choices=["simp", "solver", "factorisers", "multigrid", "direct", "mbb", "grids"])
    ap.add_argument("run", nargs="?", type=Path, help="mbb, grids: the run directory")
    ap.add_argument("--cells", type=int, nargs="+", default=[90, 135, 180, 270, 360],
                    help="grids: elements along the longest side of each grid")
    ap.add_argument("--blocks", type=int, default=3, help="solver, factorisers, multigrid: alternating blocks per configuration; "
                    "direct: timed solves after the first")
    a = ap.parse_args()
    if a.what == "simp":
        run_simp()
    elif a.what == "solver":
        run_solver(a.blocks)
    elif a.what == "factorisers":
        factorisers(a.blocks)
    elif a.what == "multigrid":
        run_multigrid(a.blocks)
    elif a.what == "direct":
        run_direct(a.blocks)
    else:
        if a.run is None:
            ap.error(f"{a.what} needs the run directory")
        if a.what == "grids":
            run_on_grids(a.run, a.cells)
        else:
            run_against_simp(a.run)


if __name__ == "__main__":
    main()
