"""Run settings derived from a shape problem's geometry, for whatever its spec does not state.

A spec written by a user holds geometry, tolerances and perhaps the number of shapes; everything
else comes from here. The length scale is ``s`` = half the longest side of the domain. The network
works in the domain's frame (``model.frame: domain``), so its settings do not depend on ``s``; each
loss weight carries the power of ``s`` that makes its term's contribution independent of the
problem's size (a field that is a distance scales like ``s``). At ``s = 1`` the loss weights and
point counts are the obstacle's ``quick`` preset's; the first-layer frequency follows
the interfaces and the tolerance (14.1 instead of 5 at the default tolerance) and ``latent_scale``
stays 1 (``docs/results.md``, "Problem suite", for what they reach):

==================  ==============================  =============================================
setting             value                           why
==================  ==============================  =============================================
model               SIREN 4 x 64 (2D), 3 x 128      the widths of the obstacle (2D) and bracket
                    (3D)                            (3D) CPU presets
model.w0_first      max(5, s / (2 a), sqrt(s / h)), an interface of size a needs about s / a
                    a the smallest interface        oscillations per half domain; a field that
                    (:func:`smallest_feature`), h   must meet the interfaces to within h needs
                    the interface tolerance times   corners sharper than a smooth first layer
                    ``unit_scale``                  draws: on the obstacle (4 shapes, 2000
                                                    iterations) omega 5, 8, 12 gave the worst
                                                    CD1 7.1e-3, 4.6e-3, 2.6e-3 (bound 5e-3);
                                                    sqrt(s / h) is 14 at the default tolerance
model.frame         domain                          the network sees the domain as [-1, 1] along
                                                    its longest side and returns distances in
                                                    units of s (:mod:`ginn.models.frame`)
interface           3000 / s^2                      mean f^2 on the interfaces scales as s^2
design_region       300 / s                         mean |min(0, f - floor)| scales as s
obstacle            1000 / s                        (``containment_power`` 1, ``slope`` 1)
normal              10                              unit vectors: no scale
eikonal             0.1                             |grad f| - 1: no scale
connectedness       8 / s, margin 0.02 s            the mean penalised field value scales as s
topology            8 / s; grid 64 (2D), 32 (3D)    hinges on field values, as connectedness
                                                    (only with ``topology:`` targets)
diversity           0.015 / s                       the aggregated shape distance scales as s
iterations          2000 (2D), 3600 (3D)            learning rate halved every third of them
                                                    (of a stated budget too: ProblemSpec.config);
                                                    the 2D budget: the obstacle (16 shapes) ended
                                                    16/16 feasible on seeds 0 and 1 with 2000,
                                                    16/16 and 14/16 with 4000 (diversity pushes the
                                                    shapes against E's boundary late in the run)
balancing           feasibility                     the weights below start the multipliers of
                                                    the constraint terms; a check that finds a
                                                    constraint violated and off track raises
                                                    them (:mod:`ginn.train.balancing`): on
                                                    the public suite all 42 runs (14
                                                    problems, seeds 0-2) end all feasible
                                                    (``docs/results.md``, "Problem suite")
points              2D: 1024 domain, 512 outside,   per shape and iteration
                    64 obstacle, 128 interface,
                    128 boundary; 3D: 2048, 1024,
                    256, 1024, 256
==================  ==============================  =============================================

The built-in ``obstacle`` and ``bracket`` specs state only their number of shapes and latent range,
so they train with these settings unless a preset (their ``paper`` preset and its variants) states
others; ``plateau`` states the paper's settings (its curvature objective is the problem).
"""

from __future__ import annotations

import math

from ..geometry.base import Box
from .problem import Problem

__all__ = ["derived_defaults", "length_scale", "half_longest_side", "smallest_feature"]


def half_longest_side(domain: Box) -> float:
    """Half the longest side of the box ``domain``."""
    return 0.5 * max(h - lo for lo, h in zip(domain.lo, domain.hi))


def length_scale(problem: Problem) -> float:
    """The problem's length scale ``s``: half the longest side of its domain."""
    return half_longest_side(problem.domain)


def smallest_feature(problem: Problem) -> float:
    """The size of the smallest interface, in the problem's units: the least half of the longest
    side of each interface's bounding box (a circle's radius, half a segment's length); the shape's
    boundary must follow the interfaces, while it only has to keep clear of obstacles.
    ``length_scale`` without interfaces."""
    sizes = []
    for itf in problem.interfaces:
        b = itf.bounds()
        if b is not None and float((b[1] - b[0]).max()) > 0:
            sizes.append(0.5 * float((b[1] - b[0]).max()))
    return min(sizes) if sizes else length_scale(problem)


def derived_defaults(problem: Problem) -> tuple[dict, dict[str, str]]:
    """A partial run configuration for ``problem`` and, for each setting, why (``{dotted.path: text}``)."""
    s = length_scale(problem)
    d = problem.dim
    why: dict[str, str] = {}

    def note(path: str, text: str):
        why[path] = text

    hidden = [64] * 4 if d == 2 else [128] * 3
    feature = smallest_feature(problem)
    tol = problem.tolerances.interface * problem.unit_scale
    w0 = max(5.0, 0.5 * s / feature, math.sqrt(s / tol))
    model = {"kind": "siren", "hidden": hidden, "w0_first": w0, "w0_hidden": 1.0, "frame": "domain"}
    note("model.frame", f"the network sees (x - c) / s and returns s times its output, s = {s:.4g}")
    note("model.w0_first", f"max(5, s / (2 a), sqrt(s / h)), a = {feature:.4g} the smallest interface, "
                           f"h = {tol:.4g} the interface tolerance")
    note("model.hidden", f"{len(hidden)} x {hidden[0]} for a {d}D problem")
    losses = {
        "interface": {"weight": 3000.0 / s**2},
        "design_region": {"weight": 300.0 / s},
        "obstacle": {"weight": 1000.0 / s},
        "normal": {"weight": 10.0},
        "eikonal": {"weight": 0.1},
        "connectedness": {"weight": 8.0 / s},
        "topology": {"weight": 8.0 / s},
        "diversity": {"weight": 0.015 / s},
        "containment_power": 1,
        "containment_slope": 1.0,
    }
    for k, v in (("interface", "3000 / s^2"), ("design_region", "300 / s"), ("obstacle", "1000 / s"),
                 ("connectedness", "8 / s"), ("topology", "8 / s, as connectedness"), ("diversity", "0.015 / s")):
        note(f"losses.{k}.weight", f"{v}, s = {s:.4g}")
    iterations = 2000 if d == 2 else 3600
    training = {"iterations": iterations, "lr": 1e-3, "lr_decay": 0.5, "lr_decay_every": iterations // 3}
    note("training.iterations", f"the {d}D budget")
    if d == 2:
        sampling = {"n_domain": 256, "n_outside": 512, "n_obstacle": 64, "n_interface": 128, "n_boundary": 128}
        note("sampling.n_domain", "uniform samples per shape: the eikonal term and the pool of the n_boundary surface "
                                  "samples (docs/results.md, 'Step cost')")
        conn = {"every": 5, "margin": 0.02 * s}
    else:
        sampling = {"n_domain": 2048, "n_outside": 1024, "n_obstacle": 256, "n_interface": 1024,
                    "n_boundary": 256}
        conn = {"every": 5, "grid": 10, "margin": 0.02 * s}
    note("connectedness.margin", f"0.02 s, s = {s:.4g}")
    note("balancing.method", "the weights start the multipliers; each feasibility check raises those of a constraint "
                             "it finds violated and off track")
    topo = {"grid": 64 if d == 2 else 32}
    note("topology.grid", f"{topo['grid']} nodes along the longest side ({d}D)")
    out = {"model": model, "losses": losses, "sampling": sampling, "connectedness": conn, "training": training,
           "balancing": {"method": "feasibility"}, "topology": topo}
    return out, why
