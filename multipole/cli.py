"""The ``multipole`` command (DESIGN §6).

Exit codes: 0 well-posed / success, 1 structural problems found by the check, 2 invalid input.
Errors are printed as one line without a traceback.
"""
from __future__ import annotations

import argparse
import json
import sys

from . import pipeline
from .catalogue import catalogue
from .errors import IllPosedError, MultipoleError
from .netlist import load


def _overrides(items) -> dict:
    out = {}
    for item in items or []:
        if "=" not in item:
            raise MultipoleError("bad_override", f"--set {item!r} is not NAME=VALUE", "e.g. --set mesh.c=1e9")
        name, value = item.split("=", 1)
        out[name.strip()] = value.strip()
    return out


def cmd_check(args) -> int:
    scene = load(args.file, _overrides(args.set))
    analysis = pipeline.check(scene)
    code = 0 if analysis.ok else 1
    if analysis.ok:
        try:                      # loops found while assembling belong to the report too
            analysis.diagnostics += [d for d in pipeline.equations(scene, analysis).diagnostics]
        except IllPosedError as exc:
            from .diagnostics import Diagnostic
            analysis.diagnostics.append(Diagnostic("singular_loop", exc.message, exc.fix))
            code = 1
    if args.json:
        print(json.dumps({"file": args.file, "scene": scene.name, "exit_code": code, "well_posed": code == 0,
                          "states": [s.name for s in analysis.states],
                          "derivative_causality": [s.name for s in analysis.demoted],
                          "diagnostics": [d.to_dict() for d in analysis.diagnostics]}, indent=2))
    else:
        print(f"{args.file}: {scene.name}")
        for d in analysis.diagnostics:
            print("  " + str(d).replace("\n", "\n  "))
        n_err = len([d for d in analysis.diagnostics if d.severity == "error"])
        print(f"{'well-posed' if code == 0 else 'NOT well-posed'}: {n_err} error(s), "
              f"{len(analysis.states)} state(s)")
    return code


def cmd_equations(args) -> int:
    scene = load(args.file, _overrides(args.set))
    eq = pipeline.equations(scene)
    if args.format == "text":
        print(eq.to_text(scene.outputs, steps=args.steps))
    elif args.format == "latex":
        print(eq.to_latex(scene.outputs))
    else:
        print(pipeline.model(scene).source)
    return 0


def cmd_simulate(args) -> int:
    scene = load(args.file, _overrides(args.set))
    try:
        pipeline.model(scene)
    except IllPosedError:
        analysis = pipeline.check(scene)
        print(f"{args.file}: not well-posed, nothing simulated (see 'multipole check {args.file}')", file=sys.stderr)
        for d in analysis.errors:
            print("  " + str(d).replace("\n", "\n  "), file=sys.stderr)
        return 1
    result = pipeline.run(scene, args.t_end, args.dt_out, args.solver, args.rtol, args.atol,
                          progress=False if args.quiet else None, backend=args.backend)
    print(f"{scene.name}: {result.summary()}")
    if args.out:
        result.to_csv(args.out)
        print(f"wrote {args.out}")
    if args.plot:
        result.plot(args.plot, title=f"{scene.name}: {scene.description}"[:100])
        print(f"wrote {args.plot}")
    if not args.out and not args.plot:
        names = list(result.outputs)
        print("final values: " + ", ".join(f"{n} = {result.outputs[n][-1]:.6g}" for n in names))
    return 0


def cmd_elements(args) -> int:
    types = catalogue()
    if args.type:
        if args.type not in types:
            raise MultipoleError("unknown_type", f"unknown element type {args.type!r}",
                                 "run 'multipole elements' for the list")
        print(types[args.type].describe())
        return 0
    for category in ("element", "primitive"):
        print("Primitives (teaching):" if category == "primitive" else "Elements:")
        for name, et in sorted(types.items()):
            if et.category == category:
                print(f"  {name:<16} {et.doc}")
    return 0


def _lazy(module: str, name: str):
    """A command implemented in ``multipole.<module>``, imported when it runs."""
    def run(args):
        import importlib
        return getattr(importlib.import_module(f"multipole.{module}"), name)(args)
    return run


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="multipole", description="Weber multipole simulator for drive systems")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("check", help="causality analysis: exit 0 well-posed, 1 structural problems, 2 invalid file")
    p.add_argument("file")
    p.add_argument("--json", action="store_true", help="machine-readable diagnostics")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="override a parameter")
    p.set_defaults(func=cmd_check)
    p = sub.add_parser("equations", help="print the derived explicit ODE")
    p.add_argument("file")
    p.add_argument("--format", choices=("text", "latex", "python"), default="text")
    p.add_argument("--steps", action="store_true", help="Weber's back-calculation, one substitution per line")
    p.add_argument("--set", action="append", metavar="NAME=VALUE")
    p.set_defaults(func=cmd_equations)
    p = sub.add_parser("simulate", help="simulate a scene, write CSV and a plot")
    p.add_argument("file")
    p.add_argument("--t-end", type=float)
    p.add_argument("--dt-out", type=float)
    p.add_argument("--set", action="append", metavar="NAME=VALUE")
    p.add_argument("--solver", help="auto, RK45, DOP853, Radau, BDF, LSODA, RK23")
    p.add_argument("--rtol", type=float)
    p.add_argument("--atol", type=float)
    p.add_argument("--out", help="results CSV")
    p.add_argument("--plot", help="figure (png, svg, pdf)")
    p.add_argument("--backend", help="numpy (default) or a compiled backend, see docs/performance.md")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_simulate)
    p = sub.add_parser("diagram", help="Weber-style block diagram with the causality found by the check")
    p.add_argument("file")
    p.add_argument("-o", "--output", required=True, help="figure.png or figure.svg")
    p.add_argument("--set", action="append", metavar="NAME=VALUE")
    p.set_defaults(func=_lazy("diagram", "cmd_diagram"))
    p = sub.add_parser("linearize", help="linear state-space model (python-control), eigenfrequencies, Bode plot")
    p.add_argument("file")
    p.add_argument("--bode", help="figure for the Bode plot")
    p.add_argument("--set", action="append", metavar="NAME=VALUE")
    p.set_defaults(func=_lazy("linearize", "cmd_linearize"))
    p = sub.add_parser("bench", help="speed against error: work-precision reports")
    p.add_argument("files", nargs="*")
    p.add_argument("-o", "--output", default="bench_out", help="report directory")
    p.add_argument("--quick", action="store_true", help="fewer tolerances and repeats")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_lazy("bench", "cmd_bench"))
    p = sub.add_parser("elements", help="the element catalogue")
    p.add_argument("type", nargs="?")
    p.set_defaults(func=cmd_elements)
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except MultipoleError as exc:
        print(str(exc), file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
