"""Energy domains: what the effort and the flow of a port are, and how ports meet at a node.

Weber's "intuitive" assignment is used throughout: force, torque, voltage and pressure are
efforts; velocity, angular velocity, current and volume flow are flows; power = effort * flow.

Sign rule: a port's effort and flow are counted *into* the element, so a lossless element has
``sum(e*f) == 0`` over its ports.  Where several ports meet (a connection in a netlist) they form a
node of the domain's kind:

* mechanical domains (``node_kind == "b"``): a rigid massless point — all flows (velocities) are
  equal and the efforts (forces acting on each element) sum to zero;
* electrical and hydraulic domains (``node_kind == "a"``): a potential node — all efforts
  (potentials, pressures) are equal and the flows into the elements sum to zero.

A port nobody connects takes the domain's free termination: mechanical ports are free (effort 0),
electrical and hydraulic ports are open (flow 0).
"""
from __future__ import annotations

from dataclasses import dataclass

from .errors import ModelError


@dataclass(frozen=True)
class Domain:
    """One energy domain with the names and SI units of its port variables."""

    name: str
    effort: str
    effort_unit: str
    flow: str
    flow_unit: str
    displacement: str        #: time integral of the flow
    displacement_unit: str
    momentum: str            #: time integral of the effort
    momentum_unit: str
    node_kind: str           #: "a" (common effort) or "b" (common flow)
    inertia: str = "an inertia"          #: the storage of the effort's integral, as a fix names it
    compliance: str = "a compliance"     #: the storage of the flow's integral, as a fix names it

    @property
    def across(self) -> str:
        """The port variable shared by all ports of a node: ``"f"`` for kind b, ``"e"`` for kind a."""
        return "f" if self.node_kind == "b" else "e"

    @property
    def free_variable(self) -> str:
        """The variable that is zero at an unconnected port (free end or open pin)."""
        return "e" if self.node_kind == "b" else "f"

    def imposed_sign(self, variable: str) -> int:
        """Sign between a value a source imposes on its neighbour and the source's own port variable.

        The shared (across) variable is the same on both sides of a node; the other variable
        changes sign (action and reaction, or current into one element out of the other).
        """
        return 1 if variable == self.across else -1


DOMAINS: dict[str, Domain] = {
    d.name: d
    for d in (
        Domain("rotational", "torque", "N*m", "angular velocity", "rad/s", "angle", "rad",
               "angular momentum", "N*m*s", "b", "an inertia", "a torsion spring"),
        Domain("translational", "force", "N", "velocity", "m/s", "displacement", "m",
               "momentum", "N*s", "b", "a mass", "a spring"),
        Domain("electrical", "voltage", "V", "current", "A", "charge", "C",
               "flux linkage", "V*s", "a", "an inductor", "a capacitor"),
        Domain("hydraulic", "pressure", "Pa", "volume flow", "m^3/s", "volume", "m^3",
               "pressure momentum", "Pa*s", "a", "a line inertance", "an accumulator"),
    )
}


@dataclass(frozen=True)
class Bundle:
    """A group of one-dimensional ports that a netlist joins with one connection entry.

    ``components`` are (name, domain) pairs; a bundle port ``out`` of an element is its ports
    ``out.<name>``.  Joining two bundle ports of the same kind joins their components pairwise, so a
    node of a bundle is one node per component (each with the node rule of its domain).  Power
    through a bundle port is the sum of its components' ``e*f``.  A component's displacement (the
    time integral of its flow: a position or an angle) can be handed from the element that
    determines it to the others at the node (see :class:`multipole.network.Network`, ``positions``).
    """

    name: str
    components: tuple        #: ((component name, domain name), ...)
    doc: str = ""

    def ports(self, base: str) -> list[str]:
        """The component port names of a bundle port called ``base``."""
        return [f"{base}.{c}" for c, _ in self.components]


BUNDLES: dict[str, Bundle] = {
    b.name: b
    for b in (
        Bundle("planar", (("x", "translational"), ("y", "translational"), ("phi", "rotational")),
               "planar rigid-body motion: x, y [m] and the angle phi [rad] about z; loads Fx, Fy [N] "
               "and the torque T [N*m]; power Fx*vx + Fy*vy + T*omega"),
        Bundle("band", (("l", "translational"), ("gamma", "rotational")),
               "band connection (point-to-point, never branched): l carries the band tension [N] as the "
               "effort and the band material speed [m/s] as the flow (the wound length l_r [m], its "
               "integral, is the position); gamma carries the inclination angle of the span [rad] as a "
               "position and no torque"),
    )
}


def bundle(name: "str | Bundle") -> Bundle:
    """Look up a bundle kind by name (``planar``, ``band``)."""
    if isinstance(name, Bundle):
        return name
    try:
        return BUNDLES[name]
    except KeyError:
        raise ModelError("unknown_bundle", f"unknown port bundle {name!r}",
                         f"use one of {', '.join(BUNDLES)}") from None


def domain(name: "str | Domain") -> Domain:
    """Look up a domain by name (``rotational``, ``translational``, ``electrical``, ``hydraulic``)."""
    if isinstance(name, Domain):
        return name
    try:
        return DOMAINS[name]
    except KeyError:
        raise ModelError("unknown_domain", f"unknown domain {name!r}",
                         f"use one of {', '.join(DOMAINS)}") from None
