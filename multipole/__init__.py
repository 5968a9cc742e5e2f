"""multipole — mechatronic drive systems as Weber multipoles.

Pipeline (one module per stage)::

    netlist.load ─▶ Network ─▶ network.flatten ─▶ causality.analyse ─▶ equations.assemble
        ─▶ codegen.compile_model ─▶ simulate.simulate ─▶ Result

The public API below is what element libraries and scripts build on.
"""
from .catalogue import REQUIRED, ElementType, Param, Reduction, catalogue, element, register
from .causality import Analysis, analyse
from .diagnostics import CATALOGUE as DIAGNOSTICS, Diagnostic, register as register_check
from .domains import BUNDLES, DOMAINS, Bundle, Domain
from .equations import Equations, assemble
from .errors import IllPosedError, ModelError, MultipoleError, NetlistError, RunError
from .network import ClosedForm, Closure, FlatNetwork, Monitor, Network, Quantity, Sketch, flatten
from .primitives import T, LAW_F, LAW_P, LAW_Q
from .primitives import C, CField, GY, I, MTF, R, TF, Primitive, Se, Sf, Tap, junction_a, junction_b

from .codegen import Model, compile_model
from .simulate import Result, read_csv, simulate
from .linearize import control_name, linearize_scene as linearize
from .netlist import Scene, load, loads
from . import pipeline
from . import sweep    # a callable module: multipole.sweep(scene, {...}) runs a study
from .reduce import reduce

from .checks import Context as CheckContext, position_graph   # the kernel's checks register first

__version__ = "0.1.0"

__all__ = [
    "REQUIRED", "ElementType", "Param", "Reduction", "reduce", "catalogue", "element", "register", "Analysis", "analyse", "DIAGNOSTICS",
    "Diagnostic", "register_check", "CheckContext", "position_graph", "BUNDLES", "Bundle", "DOMAINS", "Domain", "ClosedForm", "Closure", "Monitor", "Sketch", "Equations", "assemble", "IllPosedError", "ModelError",
    "MultipoleError", "NetlistError", "RunError", "FlatNetwork", "Network", "Quantity", "flatten", "C", "CField",
    "GY", "I", "MTF", "R", "TF", "Primitive", "Se", "Sf", "Tap", "junction_a", "junction_b", "T", "LAW_F", "LAW_P",
    "LAW_Q", "Model", "compile_model", "Result", "read_csv", "simulate", "linearize", "control_name", "Scene", "load", "loads", "pipeline", "sweep",
]
