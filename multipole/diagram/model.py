"""The drawing model of a block diagram: what the stages produce and :func:`~multipole.diagram.render`
draws (:class:`Block`, :class:`Arrow`, :class:`Group`, :class:`Diagram`), and the sizes and colours
all stages share.

Geometry is in drawing units: one unit is :data:`SCALE` inches in the figure.  Font sizes are in
points.
"""
from __future__ import annotations

from dataclasses import dataclass, field

#: inches per drawing unit
SCALE = 0.8

FLOW = "#1f5fa8"        #: colour of flow signals (Bewegungen)
EFFORT = "#303030"      #: colour of effort signals (Kräfte)
CONFLICT = "#d62728"    #: elements named by an error diagnostic, undetermined variables
DERIVATIVE = "#7b3fa0"  #: storage in derivative causality
POSITION = "#2e7d32"    #: position closures and the position signals that modulate transformers

#: primitives drawn as one block between the two rows (cross-couplings, sources, taps); any other
#: one-port kind an element library defines is drawn there too
MIDDLE_KINDS = ("I", "C", "R", "Se", "Sf", "Tap", "CField")
#: primitives drawn with a block in each row
ROW_KINDS = ("TF", "MTF", "GY", "junction_a", "junction_b")

DY = 1.0             #: flow row -> middle -> effort row spacing [drawing units]
LANE = 2 * DY + 1.55  #: vertical distance between stacked lanes without tracks [drawing units]
SUB = 1.25           #: smallest width of one item inside an element [drawing units]
HANG = 1.1           #: spacing of cross-couplings hanging under the same junction [drawing units]
TRACK = 0.32         #: spacing of vertical tracks in a gap between columns [drawing units]
CORRIDOR = 0.28      #: spacing of horizontal return tracks above/below the lanes [drawing units]
FONT = 8.0           #: block labels [pt]
RATIO_CHARS = 14     #: longest label written into a ratio block; longer ones go to a footnote
NOTE_CHARS = 24      #: longest second line of a block [characters]
COLLAPSE_ABOVE = 4   #: families of identical sub-elements longer than this are drawn collapsed
DRAWN_HEAD = 2       #: members drawn before the placeholder of a collapsed family (plus the last)


@dataclass
class Block:
    """One drawn block.

    ``kind``: ``sum`` (Σ), ``dot`` (branching point), ``ratio`` (TF/MTF), ``gyrator``, ``storage``
    (I, C, C-field), ``resistance`` (R), ``source`` (Se, Sf), ``tap``, ``terminal`` (an unconnected
    port), ``closure`` (a position closure, solved by its formula or Newton's method), ``other`` (a one-port kind defined by an element library), ``repeat`` (the placeholder
    of identical sub-elements drawn collapsed).
    ``row``: ``"f"`` (flow row), ``"e"`` (effort row), ``"x"`` (between the rows) or ``"p"``
    (a ``closure``: a position closure, above the lanes).
    ``owner`` is the primitive path or the node name whose equations the block stands for;
    ``element`` the top-level element it belongs to (``""`` for a node joining elements).
    ``identity`` marks blocks that only pass a value on (dots, two-port sums).
    ``bus``: a junction with many connections drawn as a line outside the rows (a branching bar
    for its common variable, a collecting line ending in a Σ for its sum).
    """

    id: str
    kind: str
    label: str
    row: str
    owner: str
    element: str
    note: str = ""
    x: float = 0.0
    y: float = 0.0
    w: float = 0.0
    h: float = 0.0
    identity: bool = False
    conflict: bool = False
    derivative: bool = False
    bus: bool = False


@dataclass
class Arrow:
    """The signal of one port variable: from the block that computes it to the one that uses it.

    ``determined`` is False when no equation computes the variable (then ``source``/``target``
    are just the two ends and the wire is drawn red and dashed without a head).
    ``points`` is the drawn route from source to target; ``drawn`` is False for the second
    variable of a two-port connection inside an element (same wire as its partner).
    ``hidden``: the variable belongs to a collapsed sub-element (no route); ``multiplicity`` > 1:
    the drawn wire stands for that many wires to or from a collapsed run.
    """

    variable: str
    row: str
    source: str
    target: str
    determined: bool = True
    colour: str = ""
    points: list = field(default_factory=list)
    head: bool = True
    drawn: bool = True
    hidden: bool = False
    multiplicity: int = 1


@dataclass
class Group:
    """The frame of one top-level element around its blocks."""

    element: str
    label: str
    x0: float
    y0: float
    x1: float
    y1: float
    conflict: bool = False


@dataclass
class Diagram:
    """Drawing model of a scene: what :func:`render` draws and what the tests inspect."""

    title: str
    subtitle: str
    blocks: dict
    arrows: list
    groups: list
    messages: list          # (colour, text) lines shown below the diagram
    lanes: int
    extent: tuple           # xmin, xmax, ymin, ymax in drawing units
    has_derivative: bool = False
    has_conflict: bool = False
    captions: tuple = ("", "")   # what the flows and efforts are, for the row captions
    lane_h: float = LANE        # vertical distance between stacked lanes
    subgroups: list = field(default_factory=list)   # frames of networks nested inside an element
    footnotes: list = field(default_factory=list)   # full texts of labels too long for their block
    links: list = field(default_factory=list)       # gyrator couplings: (points, colour) flow row <-> effort row
    collapsed: dict = field(default_factory=dict)   # placeholder block id -> hidden sub-element paths
    closures: list = field(default_factory=list)    # positions.Closure: the drawn position closures
    signals: list = field(default_factory=list)     # positions.Signal: position signals (closures, modulation)

    def arrow_of(self, variable: str) -> Arrow:
        """The arrow of a port variable (``"rotor.j.a.e"``)."""
        for a in self.arrows:
            if a.variable == variable:
                return a
        raise KeyError(variable)

    def red_elements(self) -> set:
        """Top-level elements that have at least one red block."""
        return {b.element for b in self.blocks.values() if b.conflict}
