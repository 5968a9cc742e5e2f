"""The catalogue as data: every documented parameter exists, units are stated, unknown keys refused."""
import inspect

import pytest

from helpers import scene
from multipole import NetlistError, catalogue

TYPES = sorted(catalogue())


@pytest.mark.parametrize("name", TYPES)
def test_documented_parameters_match_the_builder(name):
    et = catalogue()[name]
    assert et.doc and et.ports
    sig = inspect.signature(et.build)
    accepted = {p.name for p in sig.parameters.values() if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
    declared = {p.name for p in et.params}
    has_kwargs = any(p.kind == p.VAR_KEYWORD for p in sig.parameters.values())
    assert declared <= accepted or has_kwargs, f"{name}: builder does not take {declared - accepted}"
    assert accepted <= declared, f"{name}: builder takes undocumented {accepted - declared}"
    for p in et.params:
        assert p.doc, f"{name}.{p.name} has no description"
        if p.kind in ("number", "time", "law"):
            assert p.unit, f"{name}.{p.name} states no unit"


@pytest.mark.parametrize("name", TYPES)
def test_unknown_parameters_are_refused(name):
    with pytest.raises(NetlistError) as err:
        scene(f"elements:\n  x: {{type: {name}, no_such_parameter: 1}}\n")
    assert err.value.code == "unknown_parameter" and "no_such_parameter" in err.value.message
