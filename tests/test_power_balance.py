"""Property: on random networks of junctions, transformers and gyrators, at random states, every
junction and every transformer/gyrator conserves power (Σ e·f = 0) to 1e-12 relative."""
import numpy as np
import pytest
import sympy as sp

from multipole import C, GY, I, R, TF, Network, Se, analyse, assemble, flatten, junction_a, junction_b
from multipole.codegen import compile_model
from multipole.primitives import T


def random_network(rng):
    """Bodies (type-b junction + I) and compliances (type-a junction + C) joined by TF/GY links."""
    n_b, n_c = rng.integers(1, 4), rng.integers(1, 4)
    nodes = [("b", k) for k in range(n_b)] + [("a", k) for k in range(n_c)]
    links = []
    for k in range(1, len(nodes)):                       # a random spanning tree
        links.append((nodes[rng.integers(0, k)], nodes[k]))
    for _ in range(rng.integers(0, 3)):                  # extra links close loops
        i, j = rng.choice(len(nodes), 2, replace=False)
        links.append((nodes[i], nodes[j]))
    ports = {n: ["s"] for n in nodes}
    children, conns = {}, []
    for n in nodes:
        store = f"st_{n[0]}{n[1]}"
        children[store] = I(J=rng.uniform(0.1, 2)) if n[0] == "b" else C(c=rng.uniform(1, 50))
        conns.append([f"j_{n[0]}{n[1]}.s", f"{store}.p"])
    for k, (u, v) in enumerate(links):
        name = f"link{k}"
        kind = rng.choice(["TF", "GY"])
        children[name] = TF(rng.uniform(-3, 3)) if kind == "TF" else GY(rng.uniform(0.2, 3), "rotational", "rotational")
        ports[u].append(f"l{k}a")
        ports[v].append(f"l{k}b")
        conns += [[f"j_{u[0]}{u[1]}.l{k}a", f"{name}.a"], [f"j_{v[0]}{v[1]}.l{k}b", f"{name}.b"]]
    src = nodes[rng.integers(0, len(nodes))]
    ports[src].append("src")
    children["drive"] = Se(3 * sp.sin(T))
    conns.append([f"j_{src[0]}{src[1]}.src", "drive.p"])
    damp = nodes[rng.integers(0, len(nodes))]
    ports[damp].append("r")
    children["loss"] = R(r=rng.uniform(0.1, 1))
    conns.append([f"j_{damp[0]}{damp[1]}.r", "loss.p"])
    for n in nodes:
        signs = list(rng.choice([1, -1], len(ports[n])))
        children[f"j_{n[0]}{n[1]}"] = (junction_b if n[0] == "b" else junction_a)(ports[n], "rotational", signs)
    return Network("random", children, conns)


@pytest.mark.parametrize("seed", range(40))
def test_power_is_conserved_at_every_junction_and_transformer(seed):
    rng = np.random.default_rng(seed)
    flat = flatten(random_network(rng))
    analysis = analyse(flat)
    if not analysis.ok:
        pytest.skip("random structure not well-posed: " + analysis.errors[0].code)
    model = compile_model(assemble(analysis))
    checked = 0
    for _ in range(3):
        x = rng.normal(size=len(model.x0))
        t = rng.uniform(0, 10)
        val = model.port_values(t, x)
        for path, prim in flat.primitives.items():
            if prim.kind not in ("TF", "GY", "junction_a", "junction_b"):
                continue
            terms = [val[f"{path}.{p}.e"] * val[f"{path}.{p}.f"] for p in prim.ports]
            scale = sum(abs(v) for v in terms)
            assert abs(sum(terms)) <= 1e-12 * max(scale, 1e-300), (path, terms)
            checked += 1
    assert checked > 0


def test_enough_random_networks_are_well_posed():
    ok = sum(analyse(flatten(random_network(np.random.default_rng(s)))).ok for s in range(40))
    assert ok >= 25
