"""Weber's planetary (epicyclic) gear, built from primitives (Weber 2005, §5.7, Bild 30–33).

The planetary gear is the two-stage gear of Bild 27 whose housing turns as the carrier ``s``.
Following Bild 32, the structure adds, for each mesh, a type-a junction that splits the absolute
speed of the central wheel into the carrier speed and the speed relative to the carrier
(Weber (41)/(42): v_u10 = v_us0 + v_u1s), and joins the two carrier branches at a type-b junction
(the carrier shaft: one speed, torques add).  The meshes themselves are two spur stages working
on the relative speeds (rigid or elastic, see :mod:`elements.gears`), joined by the planet shaft
(a type-b junction).  Weber applies the wheel transducer r·ω to both summands of (41) separately;
here the sum is formed on the shaft speeds before the stage's own transducer, which is the same
linear relation (r1·ω_I = r1·ω_s + r1·ω_1s).

Nothing about Willis is typed in: the kernel derives (43)–(50) from this structure, e.g.
(ω_I − ω_s)/(ω_II − ω_s) = i0 with i0 = (−r2/r1)·(−r4/r3) (external second mesh) or
(−r2/r1)·(+r4/r3) (internal ring gear), and M_I + M_II + M_s = 0.

Ports: ``sun`` = central wheel 1 (shaft I), ``ring`` = central wheel 4 (shaft II), ``carrier`` =
the carrier (Steg) s.  Efforts are torques acting on the gear, flows angular velocities.

Planet inertia ``J_p`` (about the planet's own axis) sits on the planet's *absolute* speed
ω_p = ω_s + ω_ps, formed by a further type-a junction between the planet shaft and the carrier;
the orbiting mass of the planets belongs to the carrier inertia (an ``inertia`` on port carrier).
"""
from __future__ import annotations

import sympy as sp

from multipole import I, ModelError, Network, Param, Quantity, element, junction_a, junction_b

from .gears import spur_stage


def _relative_speed(name, children, connections, carrier_port):
    """Type-a junction ``name``: ω_central = ω_s + ω_rel (common torque), ports I, s, rel."""
    children[name] = junction_a(["I", "s", "rel"], "rotational", [1, -1, -1])
    connections.append([f"{name}.s", carrier_port])
    return f"{name}.I", f"{name}.rel"


@element("planetary", "planetary gear (Weber §5.7): sun, ring, carrier; Willis ratio from the structure; simple "
         "(z_sun, z_ring) or stepped planets (r1..r4)",
         {"sun": "central wheel 1, shaft I (rotational)", "ring": "central wheel 4, shaft II (rotational)",
          "carrier": "carrier (Steg) s (rotational)"},
         [Param("z_sun", "-", "teeth of the sun (simple planetary with ring gear)", None, positive=True),
          Param("z_ring", "-", "teeth of the ring gear (simple planetary)", None, positive=True),
          Param("module", "m", "module of the simple planetary: radius = module*z/2", 1e-3, positive=True),
          Param("r1", "m", "stepped planets: pitch radius of central wheel 1 (sun)", None, positive=True),
          Param("r2", "m", "stepped planets: pitch radius of planet wheel p1 (meshes with 1)", None, positive=True),
          Param("r3", "m", "stepped planets: pitch radius of planet wheel p2 (meshes with 4)", None, positive=True),
          Param("r4", "m", "stepped planets: pitch radius of central wheel 4", None, positive=True),
          Param("internal", "", "stepped planets: wheel 4 is an internal ring gear", False, "bool"),
          Param("c", "N/m", "mesh stiffness of both meshes (rigid meshes if omitted); a number or an expression of "
                "the mesh phase q", None, "law", law_var="q", positive=True),
          Param("d", "N*s/m", "mesh damping of both meshes", 0.0),
          Param("x0", "m", "initial deflection of the sun mesh (mounting error)", 0.0),
          Param("J_p", "kg*m^2", "spin inertia of the planet(s) about their own axis", None, positive=True)],
         {"i0": "-: fixed-carrier ratio (omega_sun - omega_s)/(omega_ring - omega_s)",
          "rolling_power": "W: power through the sun mesh in the carrier frame, M_I*(omega_I - omega_s)",
          "coupling_power": "W: power carried by the carrier rotation, M_I*omega_s",
          "mesh12.force": "N: sun-planet mesh force",
          "mesh34.force": "N: planet-ring mesh force"})
def planetary(z_sun, z_ring, module, r1, r2, r3, r4, internal, c, d, x0, J_p):
    """Build the planetary gear multipole (radii m, stiffness N/m, damping N·s/m, inertia kg·m²)."""
    stepped = [r1, r2, r3, r4]
    if z_sun is not None or z_ring is not None:
        if any(r is not None for r in stepped) or z_sun is None or z_ring is None:
            raise ModelError("conflicting_parameters", "planetary: give either z_sun and z_ring (simple planetary "
                             "with ring gear) or the stepped-planet radii r1, r2, r3, r4", "")
        if sp.sympify(z_ring - z_sun).is_number and float(z_ring - z_sun) <= 1:
            raise ModelError("bad_value", "planetary: the ring gear needs more teeth than the sun (z_ring > z_sun)")
        r_sun, r_ring = module * z_sun / 2, module * z_ring / 2
        r_planet = (r_ring - r_sun) / 2
        radii, ring_internal = (r_sun, r_planet, r_planet, r_ring), True
    else:
        if any(r is None for r in stepped):
            raise ModelError("missing_parameter", "planetary needs z_sun and z_ring, or all of r1, r2, r3, r4",
                             "e.g. z_sun: 24, z_ring: 72")
        radii, ring_internal = tuple(stepped), bool(internal)
    level = "ideal" if c is None else "elastic"
    mesh = {"level": level, "c": c, "d": d if c is not None else 0.0}
    ra, rb, rc, rd = radii
    children = {
        "carrier": junction_b(["carrier", "m12", "m34"] + (["planet"] if J_p is not None else []), "rotational"),
        "mesh12": spur_stage(ra, rb, **mesh, x0=x0 if c is not None else 0.0),
        "mesh34": spur_stage(rc, rd, internal=ring_internal, **mesh),
        "planet": junction_b(["m12", "m34"] + (["abs"] if J_p is not None else []), "rotational"),
    }
    connections: list = []
    sun, rel_sun = _relative_speed("rel_sun", children, connections, "carrier.m12")
    ring, rel_ring = _relative_speed("rel_ring", children, connections, "carrier.m34")
    connections += [[rel_sun, "mesh12.a"], ["mesh12.b", "planet.m12"], ["planet.m34", "mesh34.a"],
                    ["mesh34.b", rel_ring]]
    params = {}
    if J_p is not None:       # planet spin inertia on the absolute planet speed ω_s + ω_ps
        params["J_p"] = J_p
        children["spin"] = junction_a(["rel", "s", "I"], "rotational", [1, 1, -1])
        children["planet_I"] = I(J=sp.Symbol("J_p"))
        connections += [["planet.abs", "spin.rel"], ["carrier.planet", "spin.s"], ["spin.I", "planet_I.p"]]
    sign4 = 1 if ring_internal else -1
    i0 = (-radii[1] / radii[0]) * (sign4 * radii[3] / radii[2])
    quantities = {
        "i0": Quantity(lambda V: sp.sympify(i0).xreplace({s: V.param(s.name) for s in sp.sympify(i0).free_symbols})),
        "rolling_power": Quantity(lambda V: V.e("rel_sun.I") * (V.f("rel_sun.I") - V.f("carrier.carrier"))),
        "coupling_power": Quantity(lambda V: V.e("rel_sun.I") * V.f("carrier.carrier")),
    }
    return Network("planetary", children, connections, {"sun": sun, "ring": ring, "carrier": "carrier.carrier"},
                   params=params, quantities=quantities, doc="planetary gear (Weber Bild 32)")
