"""Holes that a 2D problem's geometry forces on every feasible shape (ginn.problems.forced)."""

from pathlib import Path

from ginn.geometry import AABox, Cylinder, Difference, Disk, Rectangle
from ginn.geometry.base import Box
from ginn.geometry.interfaces import Circle, CylinderWall, InterfaceUnion, Segment
from ginn.problems import load_spec
from ginn.problems.forced import forced_holes, forced_tunnels

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


def test_each_cylinder_wall_round_a_channel_through_the_domain_is_one_tunnel():
    box = Box((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))
    block = AABox((-0.8, -0.8, -0.3), (0.8, 0.8, 0.3))
    z, y = (0.0, 0.0, 1.0), (0.0, 1.0, 0.0)
    # two bolt holes through the block along z, one pin hole along y: three channels
    E = Difference(block, Cylinder((-0.5, 0.0, 0.0), z, 0.1, 2.5), Cylinder((0.5, 0.0, 0.0), z, 0.1, 2.5),
                   Cylinder((0.0, 0.0, 0.1), y, 0.08, 2.5))
    walls = [CylinderWall((-0.5, 0.0, 0.0), z, 0.1, 0.6), CylinderWall((0.5, 0.0, 0.0), z, 0.1, 0.6),
             InterfaceUnion([CylinderWall((0.0, -0.5, 0.1), y, 0.08, 0.3), CylinderWall((0.0, 0.5, 0.1), y, 0.08, 0.3)])]
    # the pin's two walls lie on one line: one channel, one tunnel (a lower bound)
    assert forced_tunnels(box, E, walls) == [0, 1, 2]
    # a blind hole (E closes it below the block's middle) forces nothing
    blind = Difference(block, Cylinder((-0.5, 0.0, 0.5), z, 0.1, 1.0))
    assert forced_tunnels(box, blind, [CylinderWall((-0.5, 0.0, 0.15), z, 0.1, 0.3)]) == []
    assert forced_tunnels(box, None, walls) == []


def test_the_suite_problems_force_their_through_holes():
    for name, n in (("clamp-3d", 2), ("shelf-3d", 0)):
        p = load_spec(SUITE / f"{name}.yaml").build()
        assert len(forced_tunnels(p.domain, p.design_region, p.interfaces)) == n, name
    p = load_spec("bracket").build()  # four bolt holes, and the two lugs' pin walls on one line
    assert len(forced_tunnels(p.domain, p.design_region, p.interfaces)) == 5
