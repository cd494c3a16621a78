"""The argument parser of the ``ginn`` command (what ``ginn --help`` shows; the commands live in
:mod:`ginn.cli.commands`)."""

from __future__ import annotations

import argparse
import sys

from .sweep_parser import add_sweep_parser
from .types import count, device, finite

#: the most positions ``ginn view --steps`` draws
MAX_STEPS = 4096


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line ``ginn: error: ...`` and exit status 2."""

    def error(self, message: str):
        sys.stderr.write(f"ginn: error: {message} (see `{self.prog} --help`)\n")
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="ginn", description="Geometry-informed neural networks: shapes from constraints alone.")
    sub = p.add_subparsers(dest="command", parser_class=Parser, metavar="COMMAND")

    t = sub.add_parser("train", help="train a built-in problem or a YAML spec", description="Train a GINN and write a run directory.")
    t.add_argument("problem", help="built-in problem name (see `ginn problems`) or path to a SPEC.yaml")
    t.add_argument("--preset", help="named preset of the problem (e.g. quick, demo, paper)")
    t.add_argument("--out", help="run directory (default runs/<problem>-<timestamp>)")
    t.add_argument("--device", type=device, help="cpu (default) or cuda[:N]")
    t.add_argument("--seed", type=int, help="random seed")
    t.add_argument("--iterations", type=count(1), help="number of training iterations")
    t.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                   help="override any config field, e.g. --set losses.eikonal.weight=1e-5 (repeatable)")
    t.add_argument("--quiet", action="store_true", help="no progress bar and no messages")
    t.add_argument("--no-results", action="store_true",
                   help="skip writing shapes and figures at the end (recorded: a resume does the same)")

    r = sub.add_parser("resume", help="continue a run from its last checkpoint (one writer at a time: a run "
                       "another process writes is refused), or extend a completed one with --iterations")
    r.add_argument("run_dir")
    r.add_argument("--iterations", type=count(1), help="train up to this many iterations in total (a completed run: "
                   "more than it has)")
    r.add_argument("--quiet", action="store_true", help="no progress bar and no messages")
    r.add_argument("--no-results", action="store_true", help="skip writing shapes and figures at the end")
    r.add_argument("--device", type=device, help="cpu or cuda[:N] (default: the run's)")

    st = sub.add_parser("status", help="say whether runs are running, completed, interrupted or failed")
    st.add_argument("run_dirs", nargs="+")

    pr = sub.add_parser("problems", help="list built-in problems, or print one with `show NAME`")
    pr.add_argument("action", nargs="?", choices=["list", "show"], default="list")
    pr.add_argument("name", nargs="?")

    e = sub.add_parser("eval", help="compute the paper's metrics of runs (writes RUN/metrics.json)")
    e.add_argument("run_dirs", nargs="+")
    e.add_argument("--resolution", type=count(2), help="grid cells along the longest axis (default 512 in 2D, 128 in 3D)")
    e.add_argument("--table", action="store_true", help="print a markdown table with one column per run")
    e.add_argument("--heldout", type=count(0), default=None,
                   help="held-out latent codes of a generative shape model judged beside its reported shapes, with the "
                   "smoothness of z -> shape along paths through Z (default 256 in 2D, 32 in 3D; 0: none)")
    e.add_argument("--device", type=device, help="cpu or cuda[:N] (default: the run's)")

    x = sub.add_parser("export", help="write meshes (3D) or contours (2D) for any latent value")
    x.add_argument("run_dir")
    x.add_argument("--latent", type=finite, nargs="+", action="append", help="latent value(s); repeat for several shapes")
    x.add_argument("--resolution", type=count(2), default=None, help="grid cells along the longest axis")
    x.add_argument("--format", choices=["stl", "ply", "obj"], default=None, help="mesh format of a 3D run (default stl)")
    x.add_argument("--out", help="output directory (default RUN/export)")
    x.add_argument("--device", type=device, help="cpu or cuda[:N] (default: the run's)")

    pl = sub.add_parser("plot", help="draw the paper's figures for a run (PNG)")
    pl.add_argument("run_dir")
    pl.add_argument("--resolution", type=count(2), default=None, help="grid cells along the longest axis")
    pl.add_argument("--device", type=device, help="cpu or cuda[:N] (default: the run's)")

    v = sub.add_parser("view", help="write the latent-space explorer of a run (one self-contained HTML file)")
    v.add_argument("run_dir")
    v.add_argument("--out", help="the HTML file (default RUN/figures/explorer.html)")
    v.add_argument("--steps", type=count(1, MAX_STEPS), default=64,
                   help=f"evenly spaced latent values besides the trained ones (default 64, at most {MAX_STEPS}: each is a "
                        "picture in the page, judged as ginn eval judges it)")
    v.add_argument("--device", type=device, help="cpu or cuda[:N] (default: the run's)")

    add_sweep_parser(sub)
    return p
