"""Holes that a 2D problem's geometry forces on every feasible shape (ginn.problems.forced)."""

from pathlib import Path

from ginn.geometry import Difference, Disk, Rectangle
from ginn.geometry.base import Box
from ginn.geometry.interfaces import Circle, Segment
from ginn.problems import load_spec
from ginn.problems.forced import forced_holes

SUITE = Path(__file__).resolve().parent.parent / "benchmarks" / "suite"
BOX = Box((-1.0, -1.0), (1.0, 1.0))
PLATE = Rectangle((-0.9, -0.9), (0.9, 0.9))


def test_each_circle_round_an_enclosed_part_of_X_minus_E_is_one_hole():
    E = Difference(PLATE, Disk((-0.5, 0.0), 0.1), Disk((0.5, 0.0), 0.1), Disk((0.0, 0.5), 0.1))
    faces = [Segment((-0.9, -0.9), (0.9, -0.9)), Circle((-0.5, 0.0), 0.1), Circle((0.5, 0.0), 0.1)]
    # the third disk has no circle round it: the shape may pass it on either side
    assert forced_holes(BOX, E, faces) == [1, 2]
    # a circle whose inside is E (a boss to grow round, not a hole) forces nothing
    assert forced_holes(BOX, E, [Circle((0.0, -0.5), 0.1)]) == []
    # a part that reaches beyond its circle (two disks joined by a slot outside E) is not counted:
    # the count stays a lower bound
    slot = Difference(PLATE, Disk((-0.3, 0.0), 0.1), Disk((0.3, 0.0), 0.1), Rectangle((-0.3, -0.05), (0.3, 0.05)))
    assert forced_holes(BOX, slot, [Circle((-0.3, 0.0), 0.1), Circle((0.3, 0.0), 0.1)]) == []
    # a part that reaches the domain's edge is not enclosed: no hole
    edge = Difference(Rectangle((-1.0, -1.0), (1.0, 0.9)), Disk((0.0, 0.95), 0.1))
    assert forced_holes(BOX, edge, [Circle((0.0, 0.95), 0.1)]) == []
    assert forced_holes(BOX, None, faces) == []


def test_the_suite_problems_force_their_bolt_and_pin_holes():
    for name, n in (("pins-2d", 6), ("triangle-2d", 3), ("plate-2d", 2), ("bridge-2d", 0)):
        p = load_spec(SUITE / f"{name}.yaml").build()
        assert len(forced_holes(p.domain, p.design_region, p.interfaces)) == n, name
    p = load_spec("obstacle").build()  # the disk is an obstacle, no interface round it
    assert forced_holes(p.domain, p.design_region, p.interfaces) == []
