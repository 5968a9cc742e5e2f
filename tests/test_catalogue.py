"""The catalogue as data: each parameter, unit, quantity and port declared once and built as declared, units
stated, unknown keys refused."""
import inspect
import re

import pytest
import sympy

from helpers import scene
from multipole import NetlistError, catalogue

TYPES = sorted(catalogue())


@pytest.mark.parametrize("name", TYPES)
def test_every_parameter_is_described_with_a_unit(name):
    et = catalogue()[name]
    assert et.doc and et.ports
    for p in et.params:
        assert p.doc, f"{name}.{p.name} has no description"
        if p.kind in ("number", "time", "law"):
            assert p.unit, f"{name}.{p.name} states no unit"


@pytest.mark.parametrize("name", TYPES)
def test_unknown_parameters_are_refused(name):
    with pytest.raises(NetlistError) as err:
        scene(f"elements:\n  x: {{type: {name}, no_such_parameter: 1}}\n")
    assert err.value.code == "unknown_parameter" and "no_such_parameter" in err.value.message


# -- each fact declared once: the builder's signature, the built quantities and ports match the declaration --

LAW = sympy.sympify("1e8*(1 + cos(q))")    # a mesh stiffness that varies with the mesh phase
# Configurations that together build every quantity and port a type documents (required values filled in).
SAMPLES = {
    "spring": [{"domain": "rotational"}, {"domain": "translational"}],
    "damper": [{"d": 1.0, "domain": "rotational"}, {"d": 1.0, "domain": "translational"}],
    "dc_motor": [{"L": 1e-3, "J": 1e-5}, {"L": 1e-3, "J": 1e-5, "grounded": False}],
    "piezo_stack": [{"n": 2}],
    "spur_stage": [{"r1": 0.01, "r2": 0.02}, {"r1": 0.01, "r2": 0.02, "level": "elastic", "c": LAW},
                   {"r1": 0.01, "r2": 0.02, "level": "normal", "c_n": 1e8, "z1": 20, "mu": 0.1}],
    "gear_train": [{"r1": [0.01, 0.01], "r2": [0.02, 0.02], "level": "elastic", "c": LAW}],
    "planetary": [{"z_sun": 20, "z_ring": 60, "c": 1e8}],
}
ELEMENTS = sorted(name for name, et in catalogue().items() if et.category == "element")


def _built(name):
    """Quantities (name -> unit, with those of child networks as child.name) and ports over the samples."""
    from multipole import Network
    et = catalogue()[name]
    quantities, ports = {}, set()

    def collect(net, prefix):
        quantities.update({prefix + q: v.unit for q, v in net.quantities.items()})
        for child, sub in net.children.items():
            if isinstance(sub, Network):
                collect(sub, f"{prefix}{child}.")

    for sample in SAMPLES.get(name, [{}]):
        given = {p.name: 1.0 for p in et.params if p.required}
        made = et.build(**{**given, **sample})
        bundles = getattr(made, "bundles", {})      # a bundle port is documented once, as its name
        ports |= {p for p in made.ports if p.split(".")[0] not in bundles} | set(bundles)
        if isinstance(made, Network):
            collect(made, "")
    return quantities, ports


def _matches(pattern, name):
    return re.fullmatch(re.escape(pattern).replace("<k>", r"\d+"), name) is not None


@pytest.mark.parametrize("name", TYPES)
def test_builder_signature_is_the_declared_parameter_list(name):
    """The builder takes exactly the declared parameters, in order, with the declared defaults (and none of
    its own)."""
    et = catalogue()[name]
    sig = inspect.signature(et.build).parameters
    assert [(p.name, p.default) for p in sig.values()] == \
        [(p.name, inspect.Parameter.empty if p.required else p.default) for p in et.params]
    assert all(p.default is p.empty for p in inspect.signature(et.builder).parameters.values())


@pytest.mark.parametrize("name", ELEMENTS)
def test_documented_quantities_and_ports_are_built(name):
    """Every documented quantity is built with the documented unit (one of the alternatives of a unit that
    depends on the domain), every quantity the element builds is documented, every documented port exists."""
    et = catalogue()[name]
    built, ports = _built(name)
    assert set(et.ports) == ports, name
    for qname in et.quantities:
        unit = et.quantity(qname)[0]
        hits = [b for b in built if _matches(qname, b)]
        assert hits, f"{name}: documented quantity {qname} is never built"
        assert all(built[b] in unit.split(" | ") for b in hits), (qname, unit, {b: built[b] for b in hits})
    own = {b for b in built if "." not in b}
    assert own <= set(et.quantities), f"{name}: undocumented quantities {own - set(et.quantities)}"


def test_a_builder_that_drifts_from_its_declaration_is_refused():
    """Registration refuses a builder whose arguments differ from the Params or that keeps its own defaults;
    building refuses an undeclared quantity and a unit outside the declared ones."""
    from multipole import ElementType, ModelError, Network, Param, Quantity, junction_b
    with pytest.raises(ModelError) as err:
        ElementType("x", lambda a, R_: None, "doc", {}, [Param("a", "m", "a"), Param("R", "Ohm", "r")])
    assert err.value.code == "bad_element_type" and "R_" in err.value.message
    with pytest.raises(ModelError) as err:
        ElementType("x", lambda a=2.0: None, "doc", {}, [Param("a", "m", "a", 2.0)])
    assert err.value.code == "bad_element_type"
    with pytest.raises(ModelError) as err:
        ElementType("x", lambda a, b: None, "doc", {}, [Param("a", "m", "a", 2.0), Param("b", "m", "b")])
    assert err.value.code == "bad_element_type" and "required" in err.value.message

    def net(unit):
        return Network("x", {"j": junction_b(["a", "b"], "rotational")}, ports={"a": "j.a"},
                       quantities={"w": Quantity(lambda V: V.f("j.a"), unit)})
    ok = ElementType("x", lambda unit: net(unit), "doc", {"a": "port"}, [Param("unit", "", "unit", "")],
                     {"w": "rad/s | m/s: speed"})
    assert ok.build(unit="m/s").quantities["w"].unit == "m/s"
    assert ok.build(unit="m/s").quantities["w"].doc == "speed"
    for unit, code in (("", "quantity_unit"), ("N", "quantity_unit")):
        with pytest.raises(ModelError) as err:
            ok.build(unit=unit)
        assert err.value.code == code
    bare = ElementType("x", lambda: net(""), "doc", {"a": "port"}, [])
    with pytest.raises(ModelError) as err:
        bare.build()
    assert err.value.code == "undeclared_quantity"
