"""ISO 1219-1-style circuit schematics of a circuit description, as SVG text (no drawing
library), and the reader that takes the topology back out of the drawing.

:func:`schematic_svg` draws any :class:`afo_mj.circuits.circuit.Circuit`: one symbol per
component (:data:`SYMBOLS` holds one for every kind of
:data:`afo_mj.circuits.catalogue.COMPONENT_KINDS`; a kind without one is drawn as a labelled
box, ``data-symbol="generic"``), each labelled with its name and one or two key parameters
in engineering units (cm³/rev, mm, bar, ...). Nodes are drawn as junction lines.

Layout (automatic, layered left to right): electrical supply, motor, pump, then the
hydraulic components by their distance from the pump along the oil (a node on a reservoir
does not count as a path: it joins everything), the actuators last. Components of one
column are stacked and ordered so that a port sits near the ports it joins (barycentre
sweeps); each node is a vertical junction line in the channel between two columns, or,
when it joins more than two columns, a line in each channel joined along the bottom
margin (electrical ones along the top). Lines run only in channels and margins, so no
line crosses a symbol and no two symbols overlap; a crossing without a dot is not a
connection (ISO 1219-1).

Line styles: hydraulic working line solid; pilot line (a port that passes no flow:
``unloading_valve.pilot``, ``variable_pump.sense``) dashed; electrical (the bus) blue;
mechanical (motor shaft, the driven joint) a double line.

The SVG can be read back: every component's group has ``id="comp-<name>"``,
``data-kind`` and ``data-bbox`` (its cell), every node's group ``data-node`` and
``data-ports`` (all its ``component.port``), every port's stub ``data-node`` and
``data-ports`` (its one port) and every junction line ``data-node``.
:func:`read_schematic_topology` returns ``{"components": {name: kind}, "nodes": {node:
{"component.port", ...}}}`` and checks the geometry as it reads (each stub starts in its
component's cell and ends on a junction line of its node, each node's lines are one
connected figure).
"""

from __future__ import annotations

import dataclasses
import math
import xml.etree.ElementTree as ET

from afo_mj.circuits.components import BUS, HYDRAULIC, JOINT, SHAFT

__all__ = ["schematic_geometry", "schematic_svg", "write_schematic", "read_schematic_topology",
           "SchematicError", "SYMBOLS", "LABELS", "symbol_svg", "layout_problems"]

SVG_NS = "http://www.w3.org/2000/svg"

#: ports that pass no flow: drawn as pilot lines (dashed)
PILOT_PORTS = {("unloading_valve", "pilot"), ("variable_pump", "sense")}

# geometry (px)
_FONT = 10.0            # label font size
_LINE_H = 12.0          # label line height
_ROW_GAP = 22.0         # between the cells of one column
_TRACK_SP = 11.0        # between junction lines in a channel
_CH_PAD = 14.0          # channel edge to its first junction line
_EXT = 7.0              # a port's stub leaves its symbol by this much, then turns
_EXT_STEP = 8.0         # more for each further port on the same side and facing
_MARGIN_SP = 12.0       # between margin lines
_TITLE_H = 40.0


class SchematicError(ValueError):
    """A schematic that cannot be drawn, written or read back (names what and why)."""


# ---- symbol primitives ---------------------------------------------------------------------------

def _n(x: float) -> str:
    """A coordinate as short, deterministic text."""
    s = f"{x:.2f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def _line(x1, y1, x2, y2, cls="s"):
    return f'<line class="{cls}" x1="{_n(x1)}" y1="{_n(y1)}" x2="{_n(x2)}" y2="{_n(y2)}"/>'


def _poly(points, cls="s", closed=False):
    tag = "polygon" if closed else "polyline"
    pts = " ".join(f"{_n(x)},{_n(y)}" for x, y in points)
    return f'<{tag} class="{cls}" points="{pts}"/>'


def _rect(x, y, w, h, cls="s", rx=0.0):
    r = f' rx="{_n(rx)}"' if rx else ""
    return (f'<rect class="{cls}" x="{_n(x)}" y="{_n(y)}" width="{_n(w)}" '
            f'height="{_n(h)}"{r}/>')


def _circle(cx, cy, r, cls="s"):
    return f'<circle class="{cls}" cx="{_n(cx)}" cy="{_n(cy)}" r="{_n(r)}"/>'


def _path(d, cls="s"):
    return f'<path class="{cls}" d="{d}"/>'


def _arrow(x1, y1, x2, y2, head=6.0, cls="s"):
    """A line with a filled head at (x2, y2) (a flow path through a valve box)."""
    ang = math.atan2(y2 - y1, x2 - x1)
    bx, by = x2 - head * math.cos(ang), y2 - head * math.sin(ang)
    px, py = -math.sin(ang) * head * 0.4, math.cos(ang) * head * 0.4
    return (_line(x1, y1, bx, by, cls)
            + _poly([(x2, y2), (bx + px, by + py), (bx - px, by - py)], "f", closed=True))


def _tee(x, y, dx, dy, w=5.0):
    """A blocked port inside a valve box: a stub from (x, y) along (dx, dy) ending in a bar."""
    ex, ey = x + dx, y + dy
    L = math.hypot(dx, dy) or 1.0
    px, py = -dy / L * w, dx / L * w
    return _line(x, y, ex, ey) + _line(ex - px, ey - py, ex + px, ey + py)


def _spring(x1, y1, x2, y2, turns=4, amp=4.0):
    """A zigzag spring from (x1, y1) to (x2, y2)."""
    L = math.hypot(x2 - x1, y2 - y1) or 1.0
    ux, uy = (x2 - x1) / L, (y2 - y1) / L
    px, py = -uy, ux
    pts = [(x1, y1)]
    k = 2 * turns
    for i in range(1, k):
        s = L * i / k
        sgn = amp if i % 2 else -amp
        pts.append((x1 + ux * s + px * sgn, y1 + uy * s + py * sgn))
    pts.append((x2, y2))
    return _poly(pts)


def _diag_arrow(x1, y1, x2, y2):
    """The ISO "variable / adjustable" diagonal arrow."""
    return _arrow(x1, y1, x2, y2, head=5.0)


@dataclasses.dataclass
class Symbol:
    """One drawn symbol in its own frame (centre at 0, 0): SVG ``shapes``, the ``anchors``
    where its ports leave it (port → ``(x, y, fx, fy)``, ``(fx, fy)`` the way out), its
    half width and height, upright ``texts`` (x, y, text), the orientations it may take
    (see :data:`_ORIENTS`) and the name of the symbol (the kind, or ``generic``)."""

    shapes: list
    anchors: dict
    hw: float
    hh: float
    texts: list = dataclasses.field(default_factory=list)
    orients: tuple = (0, 1)
    name: str = ""


#: orientation → (rotation deg, mirror in x first): 0 as drawn, 1 mirrored, then rotations
_ORIENTS = {0: (0, False), 1: (0, True), 2: (90, False), 3: (270, False), 4: (90, True),
            5: (270, True), 6: (180, False), 7: (180, True)}
_ALL = tuple(range(8))


def _tf(o: int, x: float, y: float) -> tuple:
    rot, mirror = _ORIENTS[o]
    if mirror:
        x = -x
    if rot == 90:
        return -y, x
    if rot == 180:
        return -x, -y
    if rot == 270:
        return y, -x
    return x, y


def _tf_attr(o: int) -> str:
    rot, mirror = _ORIENTS[o]
    out = ""
    if rot:
        out += f" rotate({rot})"
    if mirror:
        out += " scale(-1,1)"
    return out


# ---- the symbols -----------------------------------------------------------------------------

def _valve_box_2(kind_draw, hw=18.0):
    """A square valve envelope of half size ``hw`` with ports ``a`` left, ``b`` right."""
    return [_rect(-hw, -hw, 2 * hw, 2 * hw)] + kind_draw


def _sym_battery(c):
    s = [_line(-6, -14, -6, 14), _line(2, -8, 2, 8, "s thick"), _line(-14, 0, -6, 0),
         _line(2, 0, 12, 0), _line(-12, -12, -12, -6, "thin"), _line(-15, -9, -9, -9, "thin")]
    return Symbol(s, {"bus": (16, 0, 1, 0)}, 16, 16, name="battery")


def _sym_motor(c):
    # driver (PWM bridge) box with the controller's command entering it, then the motor
    s = [_rect(-40, -12, 22, 24), _path("M -36 4 L -33 4 L -33 -4 L -29 -4 L -29 4 L -26 4 "
                                        "L -26 -4 L -22 -4", "thin"),
         _line(-18, 0, -8, 0), _circle(10, 0, 18),
         _arrow(-29, -24, -29, -12, head=5.0, cls="thin"), _line(28, -2.5, 36, -2.5),
         _line(28, 2.5, 36, 2.5)]
    texts = [(10, 4, "M"), (-20, -26, "u")]
    return Symbol(s, {"bus": (-40, 0, -1, 0), "shaft": (36, 0, 1, 0)}, 40, 26, texts,
                  name="motor")


def _pump_body(r=18.0):
    tri = 6.0
    return [_circle(0, 0, r),
            _poly([(0, -r), (-tri, -r + 1.6 * tri), (tri, -r + 1.6 * tri)], "f", True),
            _poly([(0, r), (-tri, r - 1.6 * tri), (tri, r - 1.6 * tri)], "f", True),
            _line(-r - 8, -2.5, -r, -2.5), _line(-r - 8, 2.5, -r, 2.5),
            _path(f"M {_n(-r - 4)} -9 A 9 9 0 0 0 {_n(-r - 4)} 9", "thin")]


def _sym_pump(c):
    return Symbol(_pump_body(), {"a": (0, -18, 0, -1), "b": (0, 18, 0, 1),
                                 "shaft": (-26, 0, -1, 0)}, 26, 18, name="pump")


def _sym_variable_pump(c):
    s = _pump_body() + [_diag_arrow(-16, 16, 16, -16), _spring(20, -12, 34, -12, 3, 3),
                        _line(20, -16, 20, -8), _line(20, 8, 30, 8, "pilot"),
                        _line(30, 8, 30, 0, "pilot")]
    return Symbol(s, {"a": (0, -18, 0, -1), "b": (0, 18, 0, 1), "shaft": (-26, 0, -1, 0),
                      "sense": (34, 8, 1, 0)}, 34, 18, name="variable_pump")


def _sym_hose(c):
    s = [_path("M -26 0 C -14 14 14 14 26 0")]
    return Symbol(s, {"a": (-26, 0, -1, 0), "b": (26, 0, 1, 0)}, 26, 11, orients=_ALL,
                  name="hose")


def _sym_relief(c):
    # normally closed pressure valve: the flow arrow off the port line, spring above,
    # the inlet's pilot (dashed) into the opposite side
    hw = 16.0
    s = _valve_box_2([_arrow(-10, 6, 10, 6), _line(-hw - 8, 0, -hw, 0),
                      _line(hw, 0, hw + 8, 0), _spring(0, -hw, 0, -hw - 12, 3, 4),
                      _line(-6, -hw - 12, 6, -hw - 12), _diag_arrow(-8, -hw - 2, 8, -hw - 20),
                      _poly([(-hw - 5, 0), (-hw - 5, hw + 6), (0, hw + 6), (0, hw)], "pilot")],
                     hw)
    return Symbol(s, {"a": (-hw - 8, 0, -1, 0), "b": (hw + 8, 0, 1, 0)}, hw + 8, hw + 20,
                  orients=_ALL, name="relief_valve")


def _sym_unloading(c):
    # the relief valve's envelope piloted from a remote line (pilot port), no internal pilot
    hw = 16.0
    s = _valve_box_2([_arrow(-10, 6, 10, 6), _line(-hw - 8, 0, -hw, 0),
                      _line(hw, 0, hw + 8, 0), _spring(0, -hw, 0, -hw - 12, 3, 4),
                      _line(-6, -hw - 12, 6, -hw - 12), _line(0, hw, 0, hw + 10, "pilot"),
                      _line(-4, hw + 4, 4, hw + 4, "thin"),
                      _poly([(-4, hw + 10), (0, hw + 4), (4, hw + 10)], "thin")], hw)
    return Symbol(s, {"a": (-hw - 8, 0, -1, 0), "b": (hw + 8, 0, 1, 0),
                      "pilot": (0, hw + 10, 0, 1)}, hw + 8, hw + 12, orients=_ALL,
                  name="unloading_valve")


def _sym_check(c):
    # ball in a seat: the seat's apex upstream (a), the ball in its mouth: a → b passes
    s = [_line(-20, 0, -8, 0), _poly([(2, -9), (-8, 0), (2, 9)]), _circle(5, 0, 6),
         _line(11, 0, 20, 0)]
    if c is not None and getattr(c.params, "cracking_pa", 0.0) > 0.0:
        s.append(_spring(11, -9, 18, -16, 2, 2))
    return Symbol(s, {"a": (-20, 0, -1, 0), "b": (20, 0, 1, 0)}, 20, 10, orients=_ALL,
                  name="check_valve")


def _sym_flushing(c):
    # 3/3 valve piloted from both lines: left box s → a, centre closed, right box s → b
    w, h = 20.0, 20.0
    x0 = -1.5 * w
    s = [_rect(x0, -h / 2, 3 * w, h), _line(x0 + w, -h / 2, x0 + w, h / 2),
         _line(x0 + 2 * w, -h / 2, x0 + 2 * w, h / 2),
         _arrow(x0 + w / 2, h / 2, x0 + w / 2 - 5, -h / 2 + 1, head=5),
         _tee(-5, -h / 2, 0, 5, 3), _tee(5, -h / 2, 0, 5, 3), _tee(0, h / 2, 0, -5, 3),
         _arrow(x0 + 2.5 * w, h / 2, x0 + 2.5 * w + 5, -h / 2 + 1, head=5),
         _spring(x0, 0, x0 - 12, 0, 2, 3), _spring(-x0, 0, -x0 + 12, 0, 2, 3),
         _poly([(-5, -h / 2 - 6), (-x0 - 4, -h / 2 - 6), (-x0 - 4, -h / 2)], "pilot"),
         _poly([(5, -h / 2 - 9), (x0 + 4, -h / 2 - 9), (x0 + 4, -h / 2)], "pilot")]
    return Symbol(s, {"a": (-5, -h / 2, 0, -1), "b": (5, -h / 2, 0, -1),
                      "s": (0, h / 2, 0, 1)}, -x0 + 12, h / 2 + 9, orients=_ALL,
                  name="flushing_valve")


def _sym_reservoir(c):
    p = 0.0 if c is None else c.params.pressure_pa
    s = [_line(0, -16, 0, 4)]
    if p > 0.0:
        s += [_rect(-18, -8, 36, 18), _line(-18, -2, 18, -2, "thin")]
        texts = [(12, -11, "p")]
    else:
        s += [_poly([(-18, -8), (-18, 10), (18, 10), (18, -8)])]
        texts = []
    return Symbol(s, {"port": (0, -16, 0, -1)}, 18, 16, texts, name="reservoir")


def _sym_drain(c):
    """A laminar restriction (two facing arcs, the orifice's look turned upright) to an
    open tank: a pump's case drain or a seal's leak to ambient."""
    s = [_line(0, -22, 0, 10), _path("M -7 -12 C -2 -7 -2 -1 -7 4", "s"),
         _path("M 7 -12 C 2 -7 2 -1 7 4", "s"),
         _poly([(-12, 10), (-12, 22), (12, 22), (12, 10)])]
    return Symbol(s, {"port": (0, -22, 0, -1)}, 12, 22, name="drain")


def _sym_volume(c):
    s = [_line(0, -14, 0, -7), _rect(-10, -7, 20, 14, "s", rx=3),
         _line(-10, 0, 10, 0, "thin")]
    return Symbol(s, {"port": (0, -14, 0, -1)}, 10, 14, name="volume")


def _accumulator_body():
    return [_line(0, 22, 0, 16), _rect(-10, -20, 20, 36, "s", rx=10), _line(-10, -2, 10, -2),
            _poly([(0, -6), (-4, -13), (4, -13)], "f", True)]


def _sym_gas_accumulator(c):
    return Symbol(_accumulator_body(), {"port": (0, 22, 0, 1)}, 10, 22,
                  name="gas_accumulator")


def _sym_supply_accumulator(c):
    # the gas accumulator on a supply rail: a bladder (the gas engages over a band)
    s = [_line(0, 22, 0, 16), _rect(-10, -20, 20, 36, "s", rx=10),
         _path("M -6 -12 C -6 8 6 8 6 -12", "s"), _poly([(0, -8), (-3, -14), (3, -14)], "f",
                                                        True),
         _line(-14, 16, 14, 16, "thin")]
    return Symbol(s, {"port": (0, 22, 0, 1)}, 14, 22, name="supply_accumulator")


def _sym_pulley_cylinders(c):
    # piston-cable cylinder(s): the cable leaves both ends and wraps the joint pulley below
    n = 1 if c is None else int(round(c.params.count))
    s = []
    if n > 1:           # a second body behind the first: a set of cylinders on one pulley
        s.append(_poly([(-30, -10), (-30, -14), (34, -14), (34, 6), (30, 6)], "thin"))
    s += [_rect(-34, -10, 64, 20), _line(-2, -10, -2, 10, "s thick"),
          _line(-44, 0, -34, 0, "thin"), _line(30, 0, 40, 0, "thin"),
          _line(-44, 0, -16, 34, "thin"), _line(40, 0, 12, 34, "thin"),
          _circle(-2, 34, 14), _circle(-2, 34, 2, "f")]
    return Symbol(s, {"a": (-26, -10, 0, -1), "b": (22, -10, 0, -1),
                      "joint": (12, 34, 1, 0)}, 44, 48, name="pulley_cylinders")


def _sym_spring_return(c):
    s = [_rect(-34, -10, 56, 20), _line(-12, -10, -12, 10, "s thick"),
         _line(-12, 0, 36, 0, "s thick"), _spring(-10, 6, 20, 6, 4, 3),
         _line(12, -10, 12, -14, "thin"), _line(9, -14, 15, -14, "thin"),
         _line(36, -8, 36, 8), _circle(36, 0, 2, "f")]
    return Symbol(s, {"a": (-26, -10, 0, -1), "joint": (36, 0, 1, 0)}, 36, 14,
                  name="spring_return_cylinder")


def _sym_servo(c):
    # 4/3 servo valve: three boxes (parallel, closed centre, crossed), ports on the centre
    # box, continuous-positioning lines, the torque motor (coil) on the left
    w, h = 22.0, 22.0
    x0 = -1.5 * w
    s = [_rect(x0, -h / 2, 3 * w, h), _line(x0 + w, -h / 2, x0 + w, h / 2),
         _line(x0 + 2 * w, -h / 2, x0 + 2 * w, h / 2),
         _line(x0, -h / 2 - 4, -x0, -h / 2 - 4, "thin"),
         _line(x0, h / 2 + 4, -x0, h / 2 + 4, "thin"),
         _arrow(x0 + 6, h / 2, x0 + 6, -h / 2), _arrow(x0 + w - 6, -h / 2, x0 + w - 6, h / 2),
         _tee(-6, -h / 2, 0, 5, 3), _tee(6, -h / 2, 0, 5, 3), _tee(-6, h / 2, 0, -5, 3),
         _tee(6, h / 2, 0, -5, 3),
         _arrow(w / 2 + 5, h / 2, w * 1.5 - 5, -h / 2), _arrow(w * 1.5 - 5, h / 2, w / 2 + 5,
                                                               -h / 2),
         _rect(x0 - 14, -8, 14, 16), _line(x0 - 14, 8, x0, -8, "thin"),
         _spring(-x0, 0, -x0 + 10, 0, 2, 3)]
    return Symbol(s, {"a": (-6, -h / 2 - 4, 0, -1), "b": (6, -h / 2 - 4, 0, -1),
                      "p": (-6, h / 2 + 4, 0, 1), "t": (6, h / 2 + 4, 0, 1),
                      "bus": (x0 - 14, 0, -1, 0)}, -x0 + 14, h / 2 + 4, orients=(0, 1, 6, 7),
                  name="servo_valve")


def _sym_onoff(c):
    # 2/2 solenoid valve: the box at the ports is the rest position (normally open: the
    # open path; normally closed: blocked), the energised one beside it, solenoid + spring
    no = bool(c is not None and c.params.normally_open)
    w = 20.0
    rest = [_arrow(0, 10, 0, -10)] if no else [_tee(0, 10, 0, -6, 3), _tee(0, -10, 0, 6, 3)]
    other = ([_tee(-w, 10, 0, -6, 3), _tee(-w, -10, 0, 6, 3)] if no
             else [_arrow(-w, 10, -w, -10)])
    s = [_rect(-w * 1.5, -10, 2 * w, 20), _line(-w / 2, -10, -w / 2, 10)] + rest + other + [
        _rect(-w * 1.5 - 12, -7, 12, 14), _line(-w * 1.5 - 12, 7, -w * 1.5, -7, "thin"),
        _spring(w / 2, 0, w / 2 + 10, 0, 2, 3)]
    texts = [(w / 2 + 8, -12, "NO" if no else "NC")]
    return Symbol(s, {"a": (0, 10, 0, 1), "b": (0, -10, 0, -1), "bus": (-w * 1.5 - 12, 0, -1, 0)},
                  w * 1.5 + 12, 14, texts, orients=_ALL, name="onoff_valve")


def _sym_orifice(c):
    s = [_line(-20, 0, -8, 0), _line(8, 0, 20, 0), _line(-8, 0, 8, 0),
         _path("M -8 -8 C -3 -2 3 -2 8 -8", "s"), _path("M -8 8 C -3 2 3 2 8 8", "s")]
    return Symbol(s, {"a": (-20, 0, -1, 0), "b": (20, 0, 1, 0)}, 20, 9, orients=_ALL,
                  name="orifice")


def _sym_generic(c, ports=("a", "b")):
    """A labelled box for a kind without a symbol of its own: its ports spread over the
    left and right edges."""
    ports = list(ports)
    half = max(1, (len(ports) + 1) // 2)
    hh = max(14.0, 8.0 * half + 6.0)
    anchors = {}
    for i, p in enumerate(ports):
        side = -1 if i < half else 1
        k = i if i < half else i - half
        count = half if side < 0 else len(ports) - half
        y = -hh + 2 * hh * (k + 1) / (count + 1)
        anchors[p] = (side * 22.0, y, side, 0)
    s = [_rect(-22, -hh, 44, 2 * hh, "s"), _line(-22, -hh, 22, hh, "thin")]
    return Symbol(s, anchors, 22, hh, [(0, 4, "?")], orients=(0, 1), name="generic")


#: component kind → symbol function (the component, or None for its default look)
SYMBOLS = {
    "battery": _sym_battery, "motor": _sym_motor, "pump": _sym_pump,
    "variable_pump": _sym_variable_pump, "hose": _sym_hose, "relief_valve": _sym_relief,
    "check_valve": _sym_check, "flushing_valve": _sym_flushing, "reservoir": _sym_reservoir,
    "volume": _sym_volume, "gas_accumulator": _sym_gas_accumulator,
    "supply_accumulator": _sym_supply_accumulator, "pulley_cylinders": _sym_pulley_cylinders,
    "spring_return_cylinder": _sym_spring_return, "servo_valve": _sym_servo,
    "onoff_valve": _sym_onoff, "unloading_valve": _sym_unloading, "orifice": _sym_orifice,
    "drain": _sym_drain,
}


def _symbol(comp) -> Symbol:
    fn = SYMBOLS.get(comp.kind)
    sym = fn(comp) if fn else _sym_generic(comp, tuple(comp.ports))
    missing = [p for p in comp.ports if p not in sym.anchors]
    if missing:
        sym = _sym_generic(comp, tuple(comp.ports))
    return sym


def symbol_svg(kind: str) -> tuple:
    """``(symbol name, SVG markup)`` of ``kind``'s symbol with default parameters (the
    catalogue's component class built with its defaults); an unknown kind gives the generic
    box."""
    from afo_mj.circuits.catalogue import COMPONENT_KINDS
    cls = COMPONENT_KINDS.get(kind)
    if cls is None:
        sym = _sym_generic(None)
    else:
        sym = _symbol(cls("x"))
    return sym.name, "".join(sym.shapes)


# ---- labels: name and key parameters ----------------------------------------------------------

def _g(x: float) -> str:
    """Three significant figures, no exponent for ordinary sizes."""
    if x == 0:
        return "0"
    return f"{x:.3g}" if 1e-3 <= abs(x) < 1e5 else f"{x:.2e}"


def _bar(pa: float) -> str:
    return f"{_g(pa / 1e5)} bar"


def _labels_battery(p):
    b = p.battery
    return [f"{_g(b.cells_series)}S {_g(b.capacity_ah)} Ah", f"max {_g(b.max_current_a)} A"]


def _labels_motor(p):
    return [f"{_g(p.motor.torque_constant_nm_a)} N·m/A, {_g(p.motor.resistance_ohm)} Ω",
            f"driver limit {_g(p.driver.current_limit_a)} A"]


def _labels_pump(p):
    return [f"{_g(p.displacement_m3_rev * 1e6)} cm³/rev ({p.kind})"]


def _labels_variable_pump(p):
    return [f"{_g(p.pump.displacement_m3_rev * 1e6)} cm³/rev",
            f"compensator {_bar(p.compensator_pressure_pa)}"]


def _labels_hose(p):
    return [f"{_g(p.length_m)} m × Ø{_g(p.bore_m * 1e3)} mm"]


def _labels_relief(p):
    return [f"cracks at {_bar(p.cracking_dp_pa)}"]


def _labels_check(p):
    return [f"cracks at {_bar(p.cracking_pa)}"]


def _labels_flushing(p):
    return [f"shifts over {_bar(p.shift_band_pa)}"]


def _labels_reservoir(p):
    return [f"{_bar(p.pressure_pa)}" + (" (vented)" if p.pressure_pa == 0 else "")]


def _labels_volume(p):
    return [f"{_g(p.volume_m3 * 1e6)} cm³"]


def _labels_gas_accumulator(p):
    return [f"{_g(p.gas_volume_m3 * 1e6)} cm³ gas",
            f"precharge {_bar(p.precharge_pressure_pa)} abs"]


def _labels_supply_accumulator(p):
    return _labels_gas_accumulator(p.accumulator)


def _labels_pulley(p):
    cy = p.cylinder
    return [f"{_g(p.count)} × Ø{_g(cy.bore_m * 1e3)} mm, stroke {_g(cy.stroke_m * 1e3)} mm",
            f"pulley r {_g(p.pulley_radius_m * 1e3)} mm"]


def _labels_spring_return(p):
    cy = p.cylinder
    return [f"Ø{_g(cy.bore_m * 1e3)} mm, stroke {_g(cy.stroke_m * 1e3)} mm",
            f"arm {_g(p.moment_arm_m * 1e3)} mm, spring {_g(p.spring_rate_n_m / 1e3)} N/mm"]


def _labels_servo(p):
    v = p.valve
    return [f"{_g(v.rated_flow_m3_s * 6e4)} L/min at {_bar(v.rated_dp_pa)}",
            f"spool {_g(v.natural_frequency_hz)} Hz"]


def _labels_onoff(p):
    v = p.valve
    return [f"{_g(v.max_area_m2 * 1e6)} mm² open", f"switches in {_g(v.switching_time_s * 1e3)} ms"]


def _labels_unloading(p):
    return [f"out {_g(p.cut_out_pressure_pa / 1e5)} / in {_bar(p.cut_in_pressure_pa)}"]


def _labels_orifice(p):
    return [f"{_g(p.area_m2 * 1e6)} mm²"]


def _labels_drain(p):
    return [f"to tank, G {p.conductance_m3:.3g} m³", "laminar (q = G Δp / μ)"]


#: component kind → its key parameters as label lines (engineering units, unit stated)
LABELS = {
    "battery": _labels_battery, "motor": _labels_motor, "pump": _labels_pump,
    "variable_pump": _labels_variable_pump, "hose": _labels_hose,
    "relief_valve": _labels_relief, "check_valve": _labels_check,
    "flushing_valve": _labels_flushing, "reservoir": _labels_reservoir,
    "volume": _labels_volume, "gas_accumulator": _labels_gas_accumulator,
    "supply_accumulator": _labels_supply_accumulator, "pulley_cylinders": _labels_pulley,
    "spring_return_cylinder": _labels_spring_return, "servo_valve": _labels_servo,
    "onoff_valve": _labels_onoff, "unloading_valve": _labels_unloading,
    "orifice": _labels_orifice, "drain": _labels_drain,
}


def _labels(comp) -> list:
    fn = LABELS.get(comp.kind)
    lines = fn(comp.params) if fn else [f"kind {comp.kind}"]
    return [comp.name] + list(lines)[:2]


def _text_w(s: str, size: float = _FONT) -> float:
    return 0.6 * size * len(s)


# ---- layout ------------------------------------------------------------------------------------

@dataclasses.dataclass
class _Placed:
    comp: object
    sym: Symbol
    col: int = 0
    orient: int = 0
    side: dict = dataclasses.field(default_factory=dict)      # port → −1 left, +1 right
    stub: dict = dataclasses.field(default_factory=dict)      # port → local polyline
    top: float = 0.0                                           # local extents of the cell
    bottom: float = 0.0
    label_y: float = 0.0
    labels: list = dataclasses.field(default_factory=list)
    x: float = 0.0                                             # cell centre x, symbol y
    y: float = 0.0
    width: float = 0.0


def _columns(circuit, members, boundary) -> dict:
    """Column of every component (see the module docstring)."""
    comps = circuit.components
    by = {c.name: c for c in comps}
    doms = {c.name: set(c.ports.values()) for c in comps}
    converters = [c.name for c in comps if SHAFT in doms[c.name] and HYDRAULIC in doms[c.name]]
    actuators = [c.name for c in comps if JOINT in doms[c.name]]
    dry = [c.name for c in comps if HYDRAULIC not in doms[c.name]]

    def nbrs(name, domains, through_boundary=False):
        out = []
        for port, dom in by[name].ports.items():
            if dom not in domains:
                continue
            node = circuit.port_node[(name, port)]
            if node in boundary and not through_boundary:
                continue
            out += [m for m, _ in members[node] if m != name]
        return out

    col: dict = {}
    seeds = converters or [c for c in (x.name for x in comps)
                           if c not in actuators and c not in dry][:1]
    frontier = list(seeds)
    for s in seeds:
        col[s] = 0
    while frontier:
        nxt = []
        for name in frontier:
            if name in actuators:
                continue
            for m in nbrs(name, {HYDRAULIC}):
                if m not in col and m not in dry:
                    col[m] = col[name] + 1
                    nxt.append(m)
        frontier = nxt
    last = max([v for k, v in col.items() if k not in actuators] + [0]) + 1
    for a in actuators:
        col[a] = last
    # what the pump side does not reach, from the actuators backwards
    frontier = list(actuators)
    dist = {a: 0 for a in actuators}
    while frontier:
        nxt = []
        for name in frontier:
            for m in nbrs(name, {HYDRAULIC}):
                if m not in dist and m not in dry and m not in converters:
                    dist[m] = dist[name] + 1
                    nxt.append(m)
                    if m not in col:
                        col[m] = max(1, last - dist[m])
        frontier = nxt
    # the rest (on boundary nodes only, or not joined to the pump or actuators)
    for _ in range(len(comps)):
        for c in comps:
            if c.name in col or c.name in dry:
                continue
            seen = [col[m] for m in nbrs(c.name, {HYDRAULIC}, through_boundary=True)
                    if m in col]
            if seen:
                col[c.name] = min(max(min(seen) + 1, 0), last)
    for c in comps:
        if c.name not in col and c.name not in dry:
            col[c.name] = 0
    # electrical and mechanical parts: left of what they drive
    for _ in range(len(comps)):
        for name in dry:
            seen = [col[m] for m in nbrs(name, {SHAFT, BUS, JOINT}, True) if m in col
                    and m not in dry]
            seen_dry = [col[m] for m in nbrs(name, {SHAFT, BUS, JOINT}, True) if m in col
                        and m in dry]
            if SHAFT in doms[name] and seen:
                col[name] = min(seen) - 1
            elif seen_dry:
                col[name] = min(seen_dry) - 1
    for name in dry:
        col.setdefault(name, min(col.values(), default=0) - 1)
    lo = min(col.values())
    return {k: v - lo for k, v in col.items()}


def _port_pos(order: dict, index: dict) -> dict:
    """Normalised vertical position of every port (its component's place in its column,
    then the port's place in the component)."""
    pos = {}
    for name, (comp, n_in_col) in order.items():
        k = index[name]
        ports = list(comp.ports)
        for j, p in enumerate(ports):
            pos[(name, p)] = (k + (j + 0.5) / len(ports)) / max(n_in_col, 1)
    return pos


def _order_columns(circuit, col, members, skip) -> list:
    """Components of each column, top to bottom (barycentre sweeps over the ports)."""
    ncol = max(col.values()) + 1
    cols = [[c for c in circuit.components if col[c.name] == k] for k in range(ncol)]
    for sweep in range(6):
        index = {c.name: i for column in cols for i, c in enumerate(column)}
        info = {c.name: (c, len(cols[col[c.name]])) for c in circuit.components}
        pos = _port_pos(info, index)
        ks = range(1, ncol) if sweep % 2 == 0 else range(ncol - 2, -1, -1)
        for k in ks:
            ref = k - 1 if sweep % 2 == 0 else k + 1
            keys = {}
            for c in cols[k]:
                vals = []
                for port in c.ports:
                    node = circuit.port_node[(c.name, port)]
                    if node in skip:
                        continue
                    vals += [pos[m] for m in members[node] if col[m[0]] in (ref, k)
                             and m[0] != c.name]
                keys[c.name] = sum(vals) / len(vals) if vals else pos[(c.name, next(iter(
                    c.ports)))]
            cols[k] = sorted(cols[k], key=lambda c: (round(keys[c.name], 6), index[c.name]))
    return cols


def _orient_and_stubs(pl: _Placed, want: dict) -> None:
    """Choose the orientation whose anchors best face their sides (and keep the ports in
    the vertical order ``want`` asks), then route each port's stub from its anchor out of
    the symbol and to the cell edge (local coordinates; the edge is filled in later)."""
    sym = pl.sym
    best = None
    for o in sym.orients:
        cost = 0.01 * o
        placed = {}
        for port, (x, y, fx, fy) in sym.anchors.items():
            tx, ty = _tf(o, x, y)
            tfx, tfy = _tf(o, fx, fy)
            s = pl.side[port]
            cost += -s * tx * 0.05
            if tfx * s < -0.5:
                cost += 100.0
            placed[port] = (tx, ty)
        for side in (-1, 1):
            ports = [p for p in sym.anchors if pl.side[p] == side]
            for i, p in enumerate(ports):
                for q in ports[i + 1:]:
                    if (want[p] - want[q]) * (placed[p][1] - placed[q][1]) < 0:
                        cost += 5.0
        if best is None or cost < best[0] - 1e-9:
            best = (cost, o)
    pl.orient = o = best[1]
    # bounding box of the oriented symbol
    corners = [_tf(o, sx * sym.hw, sy * sym.hh) for sx in (-1, 1) for sy in (-1, 1)]
    bx0, bx1 = min(x for x, _ in corners), max(x for x, _ in corners)
    by0, by1 = min(y for _, y in corners), max(y for _, y in corners)
    stubs = {}
    for side in (-1, 1):
        ports = [p for p in sym.anchors if pl.side[p] == side]
        info = []
        for p in ports:
            x, y, fx, fy = sym.anchors[p]
            tx, ty = _tf(o, x, y)
            tfx, tfy = _tf(o, fx, fy)
            info.append((p, tx, ty, round(tfx), round(tfy)))
        # ports leaving up (down): the one nearest the side turns first
        for direction in (-1, 1):
            vert = sorted([i for i in info if i[4] == direction and i[3] == 0],
                          key=lambda i: -side * i[1])
            for k, (p, tx, ty, _, _) in enumerate(vert):
                edge_y = by0 if direction < 0 else by1
                yy = edge_y + direction * (_EXT + _EXT_STEP * k)
                stubs[p] = [(tx, ty), (tx, yy), (None, yy)]
        for p, tx, ty, fx, fy in info:
            if fy != 0 and fx == 0:
                continue
            if fx == side:
                stubs[p] = [(tx, ty), (None, ty)]
            else:
                # facing away from its side: out, around the symbol, then to the side
                ox = tx + fx * _EXT
                yy = by1 + _EXT + _EXT_STEP * 3
                stubs[p] = [(tx, ty), (ox, ty), (ox, yy), (None, yy)]
    pl.stub = stubs
    ys = [y for pts in stubs.values() for _, y in pts] + [by0, by1]
    pl.top, pl.bottom = min(ys), max(ys)
    pl.bx = (bx0, bx1, by0, by1)


def _intervals_to_tracks(items) -> dict:
    """Left-edge channel routing: ``items`` (key, y0, y1) → track index, lines that do not
    overlap (with a gap) sharing a track."""
    tracks: list = []
    out = {}
    for key, y0, y1 in sorted(items, key=lambda i: (i[1], i[2], str(i[0]))):
        for t, last in enumerate(tracks):
            if last + _TRACK_SP < y0:
                tracks[t] = y1
                out[key] = t
                break
        else:
            tracks.append(y1)
            out[key] = len(tracks) - 1
    return out


def _order_tracks(tr: dict, spans: dict, ch: int, stubs: list) -> dict:
    """Reorder the junction lines of channel ``ch`` (node → track) so that the fewest stubs
    cross another line on their way in (``stubs``: node, y, −1 from the left column, +1 from
    the right); every order is tried up to 7 lines."""
    import itertools
    n = (max(tr.values()) + 1) if tr else 0
    if n < 2 or n > 7:
        return tr
    on_track = {t: [spans[(ch, node)] for node, tt in tr.items() if tt == t] for t in range(n)}

    def covers(t, y):
        return any(y0 < y < y1 for y0, y1 in on_track[t])

    best = None
    for perm in itertools.permutations(range(n)):
        cost = 0
        for node, y, frm in stubs:
            t = tr[node]
            p = perm[t]
            for t2 in range(n):
                if t2 != t and (perm[t2] < p if frm < 0 else perm[t2] > p) and covers(t2, y):
                    cost += 1
        if best is None or cost < best[0]:
            best = (cost, perm)
    perm = best[1]
    return {node: perm[t] for node, t in tr.items()}


def _terminal_label(circuit, node) -> str:
    what = {JOINT: "joint", BUS: "bench supply", SHAFT: "shaft", HYDRAULIC: "port"}[
        circuit.node_domain[node]]
    return f"{node} ({what})"


def _free_spot(box, taken, candidates):
    """The first of ``candidates`` (dx, dy) that moves ``box`` (x0, y0, x1, y1) off every
    box in ``taken`` (else the first)."""
    x0, y0, x1, y1 = box
    for dx, dy in candidates:
        b = (x0 + dx, y0 + dy, x1 + dx, y1 + dy)
        if not any(b[0] < t[2] and t[0] < b[2] and b[1] < t[3] and t[1] < b[3] for t in taken):
            return dx, dy
    return candidates[0]


def schematic_svg(circuit, title: str | None = None) -> str:
    """The ISO 1219-1-style schematic of ``circuit`` as SVG text (see the module
    docstring)."""
    comps = circuit.components
    members = {node: [tuple(r.split(".")) for r in refs] for node, refs in circuit.nodes.items()}
    boundary = {n for n, ms in members.items()
                if any(circuit.component(c).kind == "reservoir" for c, _ in ms)}
    col = _columns(circuit, members, boundary)
    skip = boundary | set(circuit.nodes_of_domain(BUS))
    cols = _order_columns(circuit, col, members, skip)
    ncol = len(cols)
    index = {c.name: i for column in cols for i, c in enumerate(column)}
    info = {c.name: (c, len(cols[col[c.name]])) for c in comps}
    pos = _port_pos(info, index)
    node_pos = {n: sum(pos[m] for m in ms) / len(ms) for n, ms in members.items()}

    # sides: towards the rest of the node
    placed = {}
    for c in comps:
        pl = _Placed(c, _symbol(c), col=col[c.name])
        k = pl.col
        for port in c.ports:
            node = circuit.port_node[(c.name, port)]
            others = [col[m] for m, _ in members[node] if m != c.name]
            left = any(o < k for o in others)
            right = any(o > k for o in others)
            dom = circuit.node_domain[node]
            if left and not right:
                pl.side[port] = -1
            elif right and not left:
                pl.side[port] = 1
            elif not others:
                pl.side[port] = -1 if dom == BUS else 1
            elif left and right:
                n_left = sum(o < k for o in others)
                n_right = sum(o > k for o in others)
                pl.side[port] = (-1 if dom == BUS or n_left > n_right else 1)
            else:                    # only in its own column
                pl.side[port] = -1 if k > 0 and dom != JOINT else 1
        want = {p: node_pos[circuit.port_node[(c.name, p)]] for p in c.ports}
        _orient_and_stubs(pl, want)
        pl.labels = _labels(c)
        placed[c.name] = pl

    # column widths, cell heights
    col_w = []
    for column in cols:
        w = 60.0
        for c in column:
            pl = placed[c.name]
            bx0, bx1 = pl.bx[0], pl.bx[1]
            half = max(-bx0, bx1, max(abs(x) for pts in pl.stub.values()
                                      for x, _ in pts if x is not None)) + 16
            w = max(w, 2 * half, max(_text_w(t) for t in pl.labels) + 16)
        col_w.append(w)

    # channel -1 .. ncol-1: which node lines run in each
    def channel_of(pl, port):
        return pl.col - 1 if pl.side[port] < 0 else pl.col

    node_channels: dict = {}
    for pl in placed.values():
        for port in pl.comp.ports:
            node = circuit.port_node[(pl.comp.name, port)]
            node_channels.setdefault(node, set()).add(channel_of(pl, port))
    multi = {n for n, chs in node_channels.items() if len(chs) > 1}
    top_nodes = sorted((n for n in multi if circuit.node_domain[n] == BUS),
                       key=lambda n: list(circuit.nodes).index(n))
    bottom_nodes = sorted((n for n in multi if circuit.node_domain[n] != BUS),
                          key=lambda n: list(circuit.nodes).index(n))

    # vertical placement
    y_top = _TITLE_H + 14 + _MARGIN_SP * len(top_nodes) + (8 if top_nodes else 0)
    col_bottom = []
    for k, column in enumerate(cols):
        y = y_top
        for c in column:
            pl = placed[c.name]
            pl.y = y - pl.top
            pl.label_y = pl.y + pl.bottom + _LINE_H + 2
            y = pl.label_y + _LINE_H * (len(pl.labels) - 1) + 4 + _ROW_GAP
        col_bottom.append(y - _ROW_GAP)
    cells_bottom = max(col_bottom + [y_top])
    top_y = {n: _TITLE_H + 10 + _MARGIN_SP * i for i, n in enumerate(top_nodes)}
    bottom_y = {n: cells_bottom + 18 + _MARGIN_SP * i for i, n in enumerate(bottom_nodes)}

    # stub heights in each channel, then tracks
    attach: dict = {}        # (channel, node) → list of (y, name, port)
    for pl in placed.values():
        for port, pts in pl.stub.items():
            node = circuit.port_node[(pl.comp.name, port)]
            attach.setdefault((channel_of(pl, port), node), []).append(
                (pl.y + pts[-1][1], pl.comp.name, port))
    spans = {}
    for (ch, node), ats in attach.items():
        ys = [a[0] for a in ats]
        y0, y1 = min(ys), max(ys)
        if node in top_y:
            y0 = top_y[node]
        if node in bottom_y:
            y1 = bottom_y[node]
        spans[(ch, node)] = (y0, y1)
    ch_w = {}
    track = {}
    for ch in range(-1, ncol):
        items = [(node, y0, y1) for (c, node), (y0, y1) in spans.items() if c == ch]
        tr = _intervals_to_tracks(items)
        stubs_in = [(node, y, -1 if placed[cname].col == ch else 1)
                    for (c, node), ats in attach.items() if c == ch for y, cname, _ in ats]
        tr = _order_tracks(tr, spans, ch, stubs_in)
        for node, t in tr.items():
            track[(ch, node)] = t
        n_tr = (max(tr.values()) + 1) if tr else 0
        w = 2 * _CH_PAD + max(n_tr - 1, 0) * _TRACK_SP
        for n in tr:
            if len(circuit.nodes[n]) == 1:       # a terminal: room for its label
                w = max(w, 2 * _CH_PAD + _text_w(_terminal_label(circuit, n), 8.0) + 10)
        if ch in (-1, ncol - 1):
            w = max(w, 24.0)
        ch_w[ch] = w
    # x positions
    x = 16.0
    ch_x0 = {}
    col_x = []
    for ch in range(-1, ncol):
        if ch >= 0:
            col_x.append(x + col_w[ch] / 2)
            x += col_w[ch]
        ch_x0[ch] = x
        x += ch_w[ch]
    width = x + 16.0
    for pl in placed.values():
        pl.x = col_x[pl.col]
        pl.width = col_w[pl.col]

    def track_x(ch, node):
        n_tr = 1 + max(t for (c, _), t in track.items() if c == ch)
        # the first line nearer the side with more ports: left-channel lines to the left
        t = track[(ch, node)]
        span = (n_tr - 1) * _TRACK_SP
        x0 = ch_x0[ch] + (ch_w[ch] - span) / 2
        return x0 + t * _TRACK_SP

    legend_y = (max(bottom_y.values()) if bottom_y else cells_bottom) + 30
    height = legend_y + 30
    legend_w = 16 + sum(32 + _text_w(t) + 24 for _, t in _LEGEND) + _text_w(_LEGEND_NOTE)
    width = max(width, legend_w + 16)

    # ---- write
    out = [f'<svg xmlns="{SVG_NS}" width="{_n(width)}" height="{_n(height)}" '
           f'viewBox="0 0 {_n(width)} {_n(height)}" data-circuit="{_esc(circuit.name)}">',
           "<style>"
           ".s{fill:none;stroke:#000;stroke-width:1.4;stroke-linejoin:round}"
           ".thick{stroke-width:3}"
           ".thin{fill:none;stroke:#000;stroke-width:0.9}"
           ".f{fill:#000;stroke:#000;stroke-width:0.5}"
           ".pilot{fill:none;stroke:#000;stroke-width:1;stroke-dasharray:4 3}"
           ".w-hydraulic{fill:none;stroke:#000;stroke-width:1.6}"
           ".w-pilot{fill:none;stroke:#000;stroke-width:1.1;stroke-dasharray:5 3}"
           ".w-bus{fill:none;stroke:#1f4fbf;stroke-width:1.2}"
           ".w-shaft,.w-joint{fill:none;stroke:#000;stroke-width:5}"
           ".w-inner{fill:none;stroke:#fff;stroke-width:2.2}"
           ".dot{fill:#000}.dot-bus{fill:#1f4fbf}"
           "text{font-family:'DejaVu Sans',Arial,sans-serif;font-size:10px;fill:#000}"
           ".name{font-weight:bold}.param{fill:#333}"
           ".node-label{font-size:8px;fill:#555;font-style:italic}"
           ".title{font-size:14px;font-weight:bold}"
           "</style>",
           f"<title>{_esc(title or circuit.name)}</title>"]
    ctrl = circuit.controller
    refs = ", ".join(f"{k}: {v}" for k, v in sorted(getattr(ctrl, "refs", {}).items())) \
        if isinstance(getattr(ctrl, "refs", None), dict) else ""
    out.append(f'<text class="title" x="16" y="22">{_esc(title or circuit.name)}</text>')
    sub = f"controller: {ctrl.kind}" + (f" ({refs})" if refs else "") + \
        f"; drives joint '{circuit.joint}'"
    out.append(f'<text class="param" x="16" y="36">{_esc(sub)}</text>')

    # components
    for c in comps:
        pl = placed[c.name]
        sym = pl.sym
        cx0 = pl.x - pl.width / 2
        cy0 = pl.y + pl.top - 4
        cy1 = pl.label_y + _LINE_H * (len(pl.labels) - 1) + 4
        bx0, bx1, by0, by1 = pl.bx
        out.append(f'<g id="comp-{_esc(c.name)}" class="component" data-kind="{_esc(c.kind)}" '
                   f'data-symbol="{sym.name}" data-bbox="{_n(cx0)} {_n(cy0)} {_n(pl.width)} '
                   f'{_n(cy1 - cy0)}" data-symbol-bbox="{_n(pl.x + bx0)} {_n(pl.y + by0)} '
                   f'{_n(bx1 - bx0)} {_n(by1 - by0)}">')
        out.append(f'<g transform="translate({_n(pl.x)},{_n(pl.y)}){_tf_attr(pl.orient)}">'
                   + "".join(sym.shapes) + "</g>")
        for tx, ty, txt in sym.texts:
            X, Y = _tf(pl.orient, tx, ty)
            out.append(f'<text x="{_n(pl.x + X)}" y="{_n(pl.y + Y)}" text-anchor="middle">'
                       f"{_esc(txt)}</text>")
        for i, line in enumerate(pl.labels):
            cls = "name" if i == 0 else "param"
            out.append(f'<text class="{cls}" x="{_n(pl.x)}" y="{_n(pl.label_y + i * _LINE_H)}" '
                       f'text-anchor="middle">{_esc(line)}</text>')
        out.append("</g>")

    # nodes (their labels kept off the symbols, the components' labels and each other)
    taken = []
    for pl in placed.values():
        bx0, bx1, by0, by1 = pl.bx
        taken.append((pl.x + bx0, pl.y + by0, pl.x + bx1, pl.y + by1))
        for i, line in enumerate(pl.labels):
            w = _text_w(line)
            ly = pl.label_y + i * _LINE_H
            taken.append((pl.x - w / 2, ly - 9, pl.x + w / 2, ly + 2))
    for node, refs in circuit.nodes.items():
        dom = circuit.node_domain[node]
        wcls = {HYDRAULIC: "w-hydraulic", BUS: "w-bus", SHAFT: "w-shaft",
                JOINT: "w-joint"}[dom]
        double = dom in (SHAFT, JOINT)
        out.append(f'<g class="node" data-node="{_esc(node)}" data-domain="{dom}" '
                   f'data-ports="{_esc(" ".join(refs))}"><title>node {_esc(node)} ({dom}): '
                   f'{_esc(", ".join(refs))}</title>')
        wires = []         # (x1, y1, x2, y2)
        dots = []
        labels = []
        for ch in sorted({ch for (ch, n) in spans if n == node}):
            y0, y1 = spans[(ch, node)]
            tx = track_x(ch, node)
            ats = attach[(ch, node)]
            if y1 > y0:
                wires.append((tx, y0, tx, y1))
            n_att = len(ats) + (1 if node in multi else 0)
            for ya, _, _ in ats:
                if n_att >= 3 or (y0 < ya < y1):
                    dots.append((tx, ya))
            if node in multi:
                ym = top_y.get(node, bottom_y.get(node))
                hx = [track_x(c2, node) for c2 in sorted({c2 for (c2, n) in spans
                                                         if n == node})]
                if tx not in (min(hx), max(hx)):
                    dots.append((tx, ym))
            if y1 > y0 and node not in multi:
                labels.append((tx + 3, y0 - 3, node))
        if node in multi:
            ym = top_y.get(node, bottom_y.get(node))
            hx = [track_x(ch, node) for ch in sorted({ch for (ch, n) in spans if n == node})]
            wires.append((min(hx), ym, max(hx), ym))
            labels.append((min(hx) + 4, ym - 3, node))
        # stubs
        for ref in refs:
            cname, port = ref.split(".")
            pl = placed[cname]
            ch = channel_of(pl, port)
            tx = track_x(ch, node)
            pts = [(pl.x + (px if px is not None else 0), pl.y + py) for px, py in
                   pl.stub[port]]
            pts[-1] = (tx, pts[-1][1])
            pilot = (pl.comp.kind, port) in PILOT_PORTS
            scls = "w-pilot" if pilot else wcls
            d = "M " + " L ".join(f"{_n(a)} {_n(b)}" for a, b in pts)
            if double:
                out.append(f'<path class="{scls} stub" d="{d}" data-node="{_esc(node)}" '
                           f'data-ports="{_esc(ref)}"/><path class="w-inner" d="{d}"/>')
            else:
                out.append(f'<path class="{scls} stub" d="{d}" data-node="{_esc(node)}" '
                           f'data-ports="{_esc(ref)}"/>')
            if len(refs) == 1:
                # a node with one port: a labelled terminal (the driven joint, a bench
                # supply)
                ex, ey = pts[-1]
                out.append(_circle(ex, ey, 4, "s").replace("/>", f' data-node="{_esc(node)}"'
                                                            ' data-terminal="1"/>'))
                txt = _terminal_label(circuit, node)
                labels.append((ex - _text_w(txt, 8.0) / 2, ey - 8, txt))
        for x1, y1, x2, y2 in wires:
            cls = wcls
            out.append(f'<line class="{cls} wire" data-node="{_esc(node)}" x1="{_n(x1)}" '
                       f'y1="{_n(y1)}" x2="{_n(x2)}" y2="{_n(y2)}"/>')
            if double:
                out.append(_line(x1, y1, x2, y2, "w-inner"))
        dcls = "dot-bus" if dom == BUS else "dot"
        for dx, dy in sorted(set(dots)):
            out.append(f'<circle class="{dcls}" cx="{_n(dx)}" cy="{_n(dy)}" r="2.6"/>')
        for lx, ly, txt in labels:
            w = _text_w(txt, 8.0)
            dx, dy = _free_spot((lx, ly - 7, lx + w, ly + 1), taken,
                                [(0, 0), (0, 10), (0, 20), (-w - 6, 0), (-w - 6, 10),
                                 (0, -9), (0, 30), (-w - 6, 20)])
            taken.append((lx + dx, ly - 7 + dy, lx + dx + w, ly + 1 + dy))
            out.append(f'<text class="node-label" x="{_n(lx + dx)}" y="{_n(ly + dy)}">'
                       f"{_esc(txt)}</text>")
        out.append("</g>")

    # legend
    lx = 16.0
    out.append('<g class="legend">')
    for cls, txt in _LEGEND:
        out.append(_line(lx, legend_y, lx + 26, legend_y, cls))
        if cls == "w-shaft":
            out.append(_line(lx, legend_y, lx + 26, legend_y, "w-inner"))
        out.append(f'<text class="param" x="{_n(lx + 32)}" y="{_n(legend_y + 3.5)}">'
                   f"{_esc(txt)}</text>")
        lx += 32 + _text_w(txt) + 24
    out.append(f'<text class="param" x="{_n(lx)}" y="{_n(legend_y + 3.5)}">'
               f"{_esc(_LEGEND_NOTE)}</text>")
    out.append("</g></svg>")
    return "\n".join(out) + "\n"


_LEGEND = (("w-hydraulic", "working line"), ("w-pilot", "pilot line"),
           ("w-bus", "electrical (bus)"), ("w-shaft", "mechanical (shaft, joint)"))
_LEGEND_NOTE = "● junction; lines crossing without a dot are not joined (ISO 1219-1 style)"


def _esc(s: str) -> str:
    return (str(s).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
            .replace('"', "&quot;"))


# ---- writing -----------------------------------------------------------------------------------

def write_schematic(circuit, path, title: str | None = None):
    """Write the schematic of ``circuit`` to ``path``: ``.svg`` (the text), or ``.png``
    (the SVG rendered by cairosvg, which needs the cairo library). Returns the path."""
    from pathlib import Path
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in (".svg", ".png"):
        raise SchematicError(f"--out = {str(path)!r}: allowed: a file name ending in .svg or "
                             ".png")
    svg = schematic_svg(circuit, title=title)
    if suffix == ".svg":
        p.write_text(svg, encoding="utf-8")
        return p
    try:
        import cairosvg
    except (ImportError, OSError) as exc:
        raise SchematicError(f"--out = {str(path)!r}: a PNG needs cairosvg and the cairo "
                             f"library ({exc}); allowed here: a .svg file") from None
    cairosvg.svg2png(bytestring=svg.encode("utf-8"), write_to=str(p), output_width=None)
    return p


# ---- reading back ------------------------------------------------------------------------------

def _nums(s: str) -> list:
    return [float(v) for v in s.replace(",", " ").split()]


def _path_points(d: str) -> list:
    toks = d.replace("M", " ").replace("L", " ").split()
    vals = [float(t) for t in toks]
    return list(zip(vals[0::2], vals[1::2]))


def _on_segment(p, seg, tol=0.6) -> bool:
    (x, y), (x1, y1, x2, y2) = p, seg
    if min(x1, x2) - tol <= x <= max(x1, x2) + tol and min(y1, y2) - tol <= y <= max(y1, y2) \
            + tol:
        # segments are axis-parallel here
        return abs((x2 - x1) * (y - y1) - (y2 - y1) * (x - x1)) <= tol * max(
            math.hypot(x2 - x1, y2 - y1), 1.0)
    return False


def _inside(p, box, tol=0.6) -> bool:
    x, y = p
    bx, by, bw, bh = box
    return bx - tol <= x <= bx + bw + tol and by - tol <= y <= by + bh + tol


def read_schematic_topology(svg_text: str) -> dict:
    """The topology drawn in a schematic written by :func:`schematic_svg`:
    ``{"components": {name: kind}, "nodes": {node: {"component.port", ...}}}``.

    Reads the components' ``id``/``data-kind`` and each port's stub (``data-node``,
    ``data-ports``), and checks the drawing as it goes: every stub starts inside its
    component's cell and ends on a line of its own node (or a terminal of a node with one
    port); every node's lines form one connected figure; every node's ``data-ports`` is the
    set of its stubs. A drawing that fails a check raises :class:`SchematicError` naming it."""
    try:
        root = ET.fromstring(svg_text)
    except ET.ParseError as exc:
        raise SchematicError(f"not an SVG document: {exc}") from None
    comps, boxes = {}, {}
    for el in root.iter():
        ident = el.get("id", "")
        if ident.startswith("comp-"):
            name = ident[5:]
            if name in comps:
                raise SchematicError(f"component {name!r} is drawn twice")
            kind = el.get("data-kind")
            if not kind:
                raise SchematicError(f"component {name!r} has no data-kind")
            comps[name] = kind
            boxes[name] = _nums(el.get("data-bbox", ""))
            if len(boxes[name]) != 4:
                raise SchematicError(f"component {name!r} has no data-bbox")
    nodes: dict = {}
    for g in root.iter(f"{{{SVG_NS}}}g"):
        node = g.get("data-node")
        if node is None:
            continue
        declared = set(g.get("data-ports", "").split())
        wires, terminals, stubs = [], [], []
        for el in g.iter():
            if el.get("data-node") not in (None, node):
                raise SchematicError(f"node {node!r} holds a line of node "
                                     f"{el.get('data-node')!r}")
            tag = el.tag.split("}")[-1]
            cls = el.get("class", "").split()
            if tag == "line" and "wire" in cls:
                wires.append(tuple(float(el.get(k)) for k in ("x1", "y1", "x2", "y2")))
            elif tag == "circle" and el.get("data-terminal"):
                terminals.append((float(el.get("cx")), float(el.get("cy"))))
            elif tag == "path" and "stub" in cls:
                stubs.append((el.get("data-ports", ""), _path_points(el.get("d", ""))))
        found = set()
        for ref, pts in stubs:
            if ref.count(".") != 1 or " " in ref:
                raise SchematicError(f"node {node!r}: a stub names {ref!r}; allowed: one "
                                     "'component.port'")
            cname = ref.split(".")[0]
            if cname not in boxes:
                raise SchematicError(f"node {node!r}: stub of {ref!r} names no drawn "
                                     "component")
            if not _inside(pts[0], boxes[cname]):
                raise SchematicError(f"node {node!r}: the stub of {ref!r} starts at "
                                     f"{pts[0]}, outside {cname!r}")
            end = pts[-1]
            if not (any(_on_segment(end, w) for w in wires)
                    or any(math.hypot(end[0] - t[0], end[1] - t[1]) < 0.6 for t in terminals)):
                raise SchematicError(f"node {node!r}: the stub of {ref!r} ends at {end}, on "
                                     "no line of its node")
            found.add(ref)
        if found != declared:
            raise SchematicError(f"node {node!r}: data-ports {sorted(declared)} but stubs "
                                 f"{sorted(found)}")
        # the node's lines are one figure
        if len(wires) > 1:
            parent = list(range(len(wires)))

            def find(i):
                while parent[i] != i:
                    parent[i] = parent[parent[i]]
                    i = parent[i]
                return i
            for i, a in enumerate(wires):
                for j, b in enumerate(wires[:i]):
                    if any(_on_segment(p, b) for p in ((a[0], a[1]), (a[2], a[3]))) or any(
                            _on_segment(p, a) for p in ((b[0], b[1]), (b[2], b[3]))):
                        parent[find(i)] = find(j)
            if len({find(i) for i in range(len(wires))}) > 1:
                raise SchematicError(f"node {node!r}: its lines are not joined into one")
        if node in nodes:
            raise SchematicError(f"node {node!r} is drawn twice")
        nodes[node] = found
    return {"components": comps, "nodes": nodes}


def schematic_geometry(svg_text: str) -> dict:
    """The drawing of a schematic written by :func:`schematic_svg` as plain geometry (SVG
    units, y down): ``{"size": (width, height), "components": {name: (x, y, w, h)},
    "nodes": {node: [polyline, ...]}}``, each node's lines and port stubs as lists of
    ``(x, y)`` points: what a viewer needs to draw the circuit and colour each node (the
    recording's live schematic, :mod:`afo_mj.outputs.recording`)."""
    try:
        root = ET.fromstring(svg_text)
    except ET.ParseError as exc:
        raise SchematicError(f"not an SVG document: {exc}") from None
    size = (float(root.get("width", 0)), float(root.get("height", 0)))
    comps = {}
    for el in root.iter():
        ident = el.get("id", "")
        if ident.startswith("comp-"):
            comps[ident[5:]] = tuple(_nums(el.get("data-bbox", "")))
    nodes: dict = {}
    for g in root.iter(f"{{{SVG_NS}}}g"):
        node = g.get("data-node")
        if node is None:
            continue
        strips = nodes.setdefault(node, [])
        for el in g.iter():
            tag = el.tag.split("}")[-1]
            cls = el.get("class", "").split()
            if tag == "line" and "wire" in cls:
                x1, y1, x2, y2 = (float(el.get(k)) for k in ("x1", "y1", "x2", "y2"))
                strips.append([(x1, y1), (x2, y2)])
            elif tag == "path" and "stub" in cls:
                strips.append(_path_points(el.get("d", "")))
    return {"size": size, "components": comps, "nodes": nodes}


def layout_problems(svg_text: str) -> list:
    """What is wrong with a schematic's layout, as sentences (empty: nothing): two
    components' cells that overlap, and a junction line that passes through a symbol."""
    root = ET.fromstring(svg_text)
    cells, syms = {}, {}
    for el in root.iter():
        ident = el.get("id", "")
        if ident.startswith("comp-"):
            cells[ident[5:]] = _nums(el.get("data-bbox"))
            syms[ident[5:]] = _nums(el.get("data-symbol-bbox"))
    out = []
    names = sorted(cells)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            ax, ay, aw, ah = cells[a]
            bx, by, bw, bh = cells[b]
            if ax < bx + bw and bx < ax + aw and ay < by + bh and by < ay + ah:
                out.append(f"cells of {a!r} and {b!r} overlap")
    for el in root.iter():
        if el.tag.split("}")[-1] != "line" or "wire" not in el.get("class", ""):
            continue
        x1, y1, x2, y2 = (float(el.get(k)) for k in ("x1", "y1", "x2", "y2"))
        for name, (sx, sy, sw, sh) in syms.items():
            if (min(x1, x2) < sx + sw and max(x1, x2) > sx and min(y1, y2) < sy + sh
                    and max(y1, y2) > sy):
                out.append(f"a line of node {el.get('data-node')!r} crosses the symbol of "
                           f"{name!r}")
    return out
