"""The ``multipole`` command (DESIGN §6).

Exit codes (docs/cli.md): 0 well-posed / success, 1 structural problems found by the check (in
every verb), 2 invalid input or options, 3 a run-time failure of a well-posed model, 130
interrupted (Ctrl-C).  Errors are printed as one line without a traceback; the code comes from
the error's class (``MultipoleError.exit_code``), mapped in one place, :func:`main`.

Run as the process's command (``main()`` reading ``sys.argv``), it leaves what the imports made
out of the cyclic garbage collector's passes, during the command and at exit
(:func:`_as_command`); docs/performance.md, "A new process on the numba backend".
"""
from __future__ import annotations

import argparse
import atexit
import gc
import json
import os
import sys
import warnings
from pathlib import Path

from . import pipeline
from .catalogue import catalogue
from .errors import IllPosedError, LongRunWarning, MultipoleError, MultipoleWarning, RunError
from .netlist import load, validate_simulate_options
from .simulate import monitor_line

#: exit status after Ctrl-C (128 + SIGINT, as shells report it)
EXIT_INTERRUPTED = 130


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
    record = pipeline.pruned(scene)[2] if args.explain and analysis.ok else None
    if args.json:
        print(json.dumps({"file": args.file, "scene": scene.name, "exit_code": code, "well_posed": code == 0,
                          "states": [s.name for s in analysis.states],
                          "derivative_causality": [s.name for s in analysis.demoted],
                          "diagnostics": [d.to_dict() for d in analysis.diagnostics],
                          **({"pruning": record.to_dict()} if record is not None else {})}, indent=2))
    else:
        print(f"{args.file}: {scene.name}")
        for d in analysis.diagnostics:
            print("  " + str(d).replace("\n", "\n  "))
        n_err = len([d for d in analysis.diagnostics if d.severity == "error"])
        n_warn = len([d for d in analysis.diagnostics if d.severity == "warning"])
        print(f"{'well-posed' if code == 0 else 'NOT well-posed'}: {n_err} error(s), "
              + (f"{n_warn} warning(s), " if n_warn else "") + f"{len(analysis.states)} state(s)")
        for line in record.lines() if record is not None else ():
            print(line)
    return code


def cmd_equations(args) -> int:
    scene = load(args.file, _overrides(args.set))
    eq = pipeline.equations(scene)
    if args.format == "text":
        print(eq.to_text(scene.outputs, steps=args.steps))
    elif args.format == "latex":
        print(eq.to_latex(scene.outputs))
    else:
        print(pipeline.model(scene).source)      # it imports the Newton solvers it calls: it runs alone
    return 0


#: figure formats ``--plot``, ``--bode`` and ``diagram -o`` accept (matplotlib writes them without
#: extra packages)
FIGURE_FORMATS = (".png", ".svg", ".pdf")

#: what ``simulate --out`` writes: comma-separated values, a header row ``t,<outputs>``
RESULT_FORMATS = (".csv",)


def check_output_path(path: str | None, formats=None, option: str = "--out") -> None:
    """Refuse, before any work is done, an output file that cannot be written: an unsupported
    suffix, a folder, a missing or read-only folder, a read-only existing file."""
    if not path:
        return
    target = Path(path)
    if target.is_dir():
        raise MultipoleError("bad_output", f"{option} {path}: is a folder, not a file",
                             f"give a file name such as {target / ('results' + (formats or ('.csv',))[0])}")
    if formats and target.suffix.lower() not in formats:
        raise MultipoleError("bad_output", f"{option} {path}: unsupported file type {target.suffix or '(none)'!r}",
                             f"use one of {', '.join(formats)}")
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.is_dir():
        raise MultipoleError("bad_output", f"{option} {path}: folder {str(folder)!r} does not exist",
                             "create it first or write elsewhere")
    if not os.access(folder, os.W_OK | os.X_OK) or (target.exists() and not os.access(target, os.W_OK)):
        raise MultipoleError("bad_output", f"{option} {path}: not writable (permission denied)",
                             "write elsewhere or fix the permissions")


def _check_numbers(args) -> None:
    """Refuse bad numbers given on the command line before any work (``--t-end``, ``--dt-out``,
    ``--rtol``, ``--atol``), with the loader's rules for the ``simulate:`` options."""
    validate_simulate_options({"t_end": args.t_end, "dt_out": args.dt_out, "rtol": args.rtol, "atol": args.atol},
                              "command line")


def _located(exc: MultipoleError, scene) -> MultipoleError:
    """``exc`` with ``where`` set to the scene file (and the line of the element a run-time error
    names); errors that already say where they are keep it."""
    element = getattr(exc, "element", None)
    if isinstance(exc, RunError) or not exc.where:
        exc.where = scene.where(element=element) if element in scene.element_lines else scene.path
    return exc


def cmd_simulate(args) -> int:
    _check_numbers(args)
    check_output_path(args.out, RESULT_FORMATS, "--out")
    check_output_path(args.plot, FIGURE_FORMATS, "--plot")
    scene = load(args.file, _overrides(args.set))
    try:        # derives the equations only when no backend's cached model can be restored
        result = pipeline.run(scene, args.t_end, args.dt_out, args.solver, args.rtol, args.atol,
                              progress=False if args.quiet else None, backend=args.backend)
    except IllPosedError:
        analysis = pipeline.check(scene)
        print(f"{args.file}: not well-posed, nothing simulated (see 'multipole check {args.file}')", file=sys.stderr)
        for d in analysis.errors:
            print("  " + str(d).replace("\n", "\n  "), file=sys.stderr)
        return 1
    except MultipoleError as exc:
        raise _located(exc, scene) from None
    except KeyboardInterrupt as exc:        # results so far are discarded: no file looks complete
        t = getattr(exc, "t", None)
        at = f" at t = {t:.6g} s" if t is not None else ""
        print(f"{args.file}: interrupted{at}; the results so far are discarded, no file written", file=sys.stderr)
        return EXIT_INTERRUPTED
    print(f"{scene.name}: {result.summary()}")
    for note in result.stats.get("warnings", []):
        print(f"multipole: warning: during the run: {note}", file=sys.stderr)
    for finding in result.monitors:
        print(f"multipole: warning: {monitor_line(finding)}", file=sys.stderr)
    written = []
    try:
        if args.out:
            result.to_csv(args.out)
            written.append(args.out)
            print(f"wrote {args.out}")
        if args.plot:
            result.plot(args.plot, title=f"{scene.name}: {scene.description}"[:100])
            written.append(args.plot)
            print(f"wrote {args.plot}")
    except KeyboardInterrupt:
        print(f"{args.file}: interrupted while writing; " + (f"kept {', '.join(written)}, " if written else "")
              + "nothing else written", file=sys.stderr)
        return EXIT_INTERRUPTED
    if not args.out and not args.plot:
        names = list(result.outputs)
        print("final values: " + ", ".join(f"{n} = {result.outputs[n][-1]:.6g}" for n in names))
    return 0


def cmd_elements(args) -> int:
    types = catalogue()
    if args.markdown:
        print("# Element reference\n\nGenerated by `multipole elements --markdown`. SI units throughout.\n")
        for category, title in (("element", "Elements"), ("primitive", "Primitives (teaching)")):
            print(f"## {title}\n")
            for name, et in sorted(types.items()):
                if et.category == category:
                    print(et.markdown())
        return 0
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


def _version() -> str:
    try:
        from importlib.metadata import version
        return version("multipole")
    except Exception:                    # not installed as a distribution: the source's own number
        from . import __version__
        return __version__


#: warnings held back so that none comes before an error line: the project's own (the check's
#: warnings that simulate repeats) are printed when the command ends, after the error line if it
#: failed; the libraries' (numpy, scipy, sympy, ...) only after a success
_HELD: list = []
_DEFERRED: list = []


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """Collect a warning as one line (see :data:`_HELD` and :data:`_DEFERRED`)."""
    if issubclass(category, LongRunWarning):     # announces a wait: now, not afterwards
        print(f"multipole: warning: {message}", file=sys.stderr)
        return
    if issubclass(category, MultipoleWarning):
        text, into = f"multipole: warning: {message}", _HELD
    else:
        text = f"multipole: warning: {category.__name__}: {str(message).splitlines()[0] if str(message) else ''}"
        into = _DEFERRED
    if text not in into:
        into.append(text)


def _print_held(texts) -> None:
    for text in texts:
        print(text, file=sys.stderr)


def _as_command() -> None:
    """Garbage collection for a process that runs one command (:func:`main` without ``argv``).

    Now: :func:`gc.freeze` the objects the imports made (module contents, alive until exit), so
    the collector's passes during the command skip them (numba's own start-up alone made its passes
    over them cost 0.1 s CPU); what the command creates is collected as usual.  At exit, after the
    atexit handlers registered later (the cache's removal of its temporary folders among them),
    freeze every object again: the final passes then neither traverse nor free the 1–2·10⁵ tracked
    objects the libraries leave alive (as cyclic garbage, that took 0.2–0.5 s CPU after the last
    line), and the memory goes back to the system with the process.  atexit handlers, module
    clean-up and the flushing of files and streams are not affected; only ``__del__`` of objects in
    reference cycles is not run, which Python never promises at exit.  A caller that passes
    ``argv`` (a test, a script) keeps its own process's collection as it is."""
    gc.freeze()
    atexit.unregister(gc.freeze)        # registered once
    atexit.register(gc.freeze)


def main(argv=None) -> int:
    if argv is None:
        _as_command()
    parser = argparse.ArgumentParser(prog="multipole", description="Weber multipole simulator for drive systems",
                                     epilog="exit codes: 0 ok, 1 structural problems, 2 invalid input or options, "
                                            "3 run-time failure, 130 interrupted (docs/cli.md)")
    parser.add_argument("--version", action="version", version=f"multipole {_version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("check", help="causality analysis: exit 0 well-posed, 1 structural problems, 2 invalid file")
    p.add_argument("file")
    p.add_argument("--json", action="store_true", help="machine-readable diagnostics")
    p.add_argument("--explain", action="store_true", help="also list what the outputs do not need (pruned)")
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
    p.add_argument("--out", help="results CSV (.csv)")
    p.add_argument("--plot", help="figure (png, svg, pdf)")
    p.add_argument("--backend", help="numpy (default) or a compiled backend, see docs/performance.md")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_simulate)
    p = sub.add_parser("diagram", help="Weber-style block diagram with the causality found by the check")
    p.add_argument("file")
    p.add_argument("-o", "--output", required=True, help="figure (png, svg, pdf)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE")
    p.set_defaults(func=_lazy("diagram", "cmd_diagram"))
    p = sub.add_parser("draw", help="the moving geometry (a linkage) at chosen instants, its paths, transfer "
                       "functions and an animation (docs/linkages.md)")
    from .drawing import add_arguments as draw_arguments
    draw_arguments(p)
    p.set_defaults(func=_lazy("drawing", "cmd_draw"))
    p = sub.add_parser("linearize", help="linear state-space model (python-control), eigenfrequencies, Bode plot")
    p.add_argument("file")
    p.add_argument("--bode", help="figure for the Bode plot")
    p.add_argument("--at", type=float, metavar="T", help="linearise about the state simulated at time T [s] "
                   "(default: t = 0, the initial state)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE")
    p.set_defaults(func=_lazy("linearize", "cmd_linearize"))
    p = sub.add_parser("bench", help="speed against error: work-precision reports")
    p.add_argument("files", nargs="*")
    p.add_argument("-o", "--output", default="bench_out", help="report directory")
    p.add_argument("--quick", action="store_true", help="fewer tolerances and repeats")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_lazy("bench", "cmd_bench"))
    p = sub.add_parser("sweep", help="parameter study: one row per run (process pool, or Dask), docs/sweeps.md")
    from .sweep import add_arguments
    add_arguments(p)
    p.set_defaults(func=_lazy("sweep", "cmd_sweep"))
    p = sub.add_parser("reduce", help="simplify a scene within a measured output error (docs/reduce.md)")
    p.add_argument("file")
    p.add_argument("--tol", type=float, default=1e-3, help="largest relative output error accepted (0 < tol < 1)")
    p.add_argument("--outputs", nargs="+", metavar="NAME", help="outputs to compare (default: the scene's)")
    p.add_argument("-o", "--output", help="the reduced netlist (.yaml)")
    p.add_argument("--report", metavar="DIR", help="folder for report.md, report.csv and outputs.png")
    p.add_argument("--set", action="append", metavar="NAME=VALUE")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_lazy("reduce", "cmd_reduce"))
    p = sub.add_parser("elements", help="the element catalogue")
    p.add_argument("type", nargs="?")
    p.add_argument("--markdown", action="store_true", help="the whole catalogue as a markdown reference")
    p.set_defaults(func=cmd_elements)
    p = sub.add_parser("export", help="FMI 2.0 Model Exchange FMU, compiled with the C compiler found (docs/fmu.md)")
    p.add_argument("file")
    p.add_argument("--fmu", required=True, help="the FMU to write (.fmu)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE")
    p.set_defaults(func=_lazy("fmu", "cmd_export"))
    args = parser.parse_args(argv)
    shown = warnings.showwarning
    warnings.showwarning = _show_warning
    _HELD.clear()
    _DEFERRED.clear()
    try:
        code = args.func(args)
        _print_held(_HELD + _DEFERRED)       # the libraries' after a success (or the check's findings) only
        return code
    except BrokenPipeError:              # output piped into `head` and the like: stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except KeyboardInterrupt:
        print(f"multipole {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (MultipoleError, OSError, MemoryError, ArithmeticError) as exc:
        if isinstance(exc, OSError):     # a file we were asked to read or write
            exc = MultipoleError("io", f"{exc.filename or ''}: {exc.strerror or exc}".lstrip(": "),
                                 "check the path and its permissions")
        elif isinstance(exc, MemoryError):
            exc = RunError("out_of_memory", f"not enough memory for {args.command}",
                           "a smaller model, a coarser output grid or a shorter horizon", getattr(args, "file", ""))
        elif not isinstance(exc, MultipoleError):   # arithmetic outside the simulation loop
            exc = RunError("arithmetic_error", f"{args.command} failed: {type(exc).__name__}: {exc}",
                           "check the expressions and parameters", getattr(args, "file", ""))
        if not exc.where and isinstance(getattr(args, "file", None), str):
            exc.where = args.file        # at least the file, where the stage did not know it
        if getattr(args, "json", False):
            print(json.dumps({"file": args.file, "exit_code": exc.exit_code, "well_posed": False,
                              "error": {"code": exc.code, "message": exc.message, "where": exc.where,
                                        "fix": exc.fix}}, indent=2))
        print(str(exc), file=sys.stderr)
        _print_held(_HELD)                   # context for the error, never before it
        return exc.exit_code
    finally:
        warnings.showwarning = shown


if __name__ == "__main__":
    sys.exit(main())
