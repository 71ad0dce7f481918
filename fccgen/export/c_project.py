"""``fccgen export model.yaml --c DIR``: a standalone C project of a model
(docs/export.md).

DIR receives the model's generated kernels, the engine's C sources (renamed to the
model's prefix by ``<name>_names.h``), the constants the Python build's set-up decided
(``<name>_data.h``), the API (``<name>.h``, ``<name>_api.c``), ``example.c``,
``selftest.c`` (golden values of a Python run at export time), ``Makefile``,
``CMakeLists.txt`` and ``README.md``; for a model with events or turn-counting springs
also the event kernels (``events.c``, ``events.h``) and their settings (fccgen.export
.c_events). It builds with a C99 compiler and libm alone.
"""
from __future__ import annotations

import re
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..version import __version__
from ..errors import FccgenError
from ..render.escape import c_identifier
from . import c_data, c_events, c_sens
from .c_outputs import DRIVER, LEFT_OUT, OutputTable
from .c_params import parameter_map

RUNTIME = Path(__file__).resolve().parents[1] / "runtime"
ENGINE = RUNTIME / "engine"
# the key rules the C side checks (0 any finite number, 1 positive, 2 >= 0)
RULES = {"mass": 1, "inertia": 1, "stiffness": 2, "damping": 2}
GOLDEN_ROWS = 6


class ExportError(FccgenError):
    """A model the export cannot take, or a folder it cannot write."""


def environment():
    """Jinja2 over templates/export with the escaping filters only."""
    import jinja2

    from ..render import templates_root
    from ..render.escape import FILTERS
    root = templates_root() / "export"
    texts = {t.name: t.read_text(encoding="utf-8") for t in root.iterdir()
             if t.name.endswith(".jinja")}
    env = jinja2.Environment(loader=jinja2.DictLoader(texts),
                             undefined=jinja2.StrictUndefined, autoescape=False,
                             trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True)
    env.filters.update(FILTERS)
    return env


# the simulate: methods the exported engine runs, and their codes in NAME_data.h (METHOD)
EXPORTED_METHODS = {"rk4": 0, "baumgarte": 1, "dopri5": 2}


def refusal(plan) -> str:
    """Why the export cannot take this model ("" if it can)."""
    method = plan.model.simulate.method
    if method not in EXPORTED_METHODS:
        return (f"its simulate: method is {method}; the export runs "
                f"{', '.join(EXPORTED_METHODS)} (set e.g. simulate: {{method: rk4}} in "
                "the model file)")
    return ""


def method_constants(plan) -> str:
    """The run's method and schedule as NAME_data.h defines: the model's simulate:
    section with the method's defaults, as simulate takes them. METHOD, its options,
    and DT, T_END, N_STEPS, EVERY: the records are at k DT for k = 0, EVERY, 2 EVERY,
    ... below N_STEPS, then T_END (a fixed-step method: its steps of DT; dopri5: DT is
    output_dt, its records' spacing, and EVERY 1)."""
    from ..settings import methods as registry
    from ..runtime.solver import METHODS
    d = plan.model.simulate
    method = registry.get(d.method, METHODS)
    opts = registry.options_for(method)
    sched = registry.schedule(method, d, options=opts)
    out = [c_data.define("METHOD", EXPORTED_METHODS[method.name])]
    if method.name == "baumgarte":
        out += [c_data.define("BAUMGARTE_ALPHA", float(opts["alpha"])),
                c_data.define("BAUMGARTE_BETA", float(opts["beta"]))]
    if method.kind == "adaptive":
        from ..runtime._dopri5 import output_times
        times = output_times(sched.t_end, sched.output_dt)
        # simulate takes dt as the first step only when it is given to the run, not
        # from the model file: 0, Hairer's automatic first step
        out += [c_data.define("DOPRI5_RTOL", float(opts["rtol"])),
                c_data.define("DOPRI5_ATOL", float(opts["atol"])),
                c_data.define("DOPRI5_H0", float(sched.dt or 0.0)),
                c_data.define("DT", sched.output_dt), c_data.define("T_END", sched.t_end),
                c_data.define("N_STEPS", len(times) - 1), c_data.define("EVERY", 1)]
    else:
        out += [c_data.define("DT", sched.dt), c_data.define("T_END", sched.t_end),
                c_data.define("N_STEPS", sched.n_steps),
                c_data.define("EVERY", sched.every)]
    return "".join(out)


def python_run(solver, event_location="steps"):
    """The Python build's run of the model's simulate: settings on the sparse path,
    without reactions (the golden values and the decided rank); event_location: how
    its events are located (the export's default, simulate's event_location)."""
    result = solver.simulate(reactions=False, event_location=event_location)
    info = result.info
    unconverged = info.get("sparse_unconverged", 0) or 0
    if unconverged:
        raise ExportError(f"{solver.plan.model.source}: {unconverged} sparse solve(s) of "
                          "the run needed the dense fallback, which the export has not")
    return result


def engine_symbols() -> list[str]:
    """The engine's lower-case fcc_ names (functions, types, tags), not macros."""
    text = "".join(p.read_text() for p in sorted(ENGINE.glob("*.[ch]")))
    text += (RUNTIME / "fccgen_model.h").read_text() + (RUNTIME / "fccgen_events.h").read_text()
    names = set(re.findall(r"\bfcc_[a-z0-9_]+\b", text))
    macros = set(re.findall(r"#\s*define\s+(fcc_[a-z0-9_]+)", text))
    return sorted(names - macros)


def names_header(name: str, table: str, events_table: str | None = None,
                 dp_table: str | None = None) -> str:
    out = [f"/* {name}_names.h: every external name of the engine and the kernels under the\n"
           f" * prefix {name}_, so that several exported models link into one program.\n"
           " * Generated by fccgen export; do not edit. */\n",
           f"#ifndef {name.upper()}_NAMES_H\n#define {name.upper()}_NAMES_H\n"]
    for sym in engine_symbols():
        out.append(f"#define {sym} {name}_{sym}\n")
    out.append(f"#define {c_identifier(table)} {name}_kernel_table\n")
    if events_table is not None:
        out.append(f"#define {c_identifier(events_table)} {name}_event_table\n")
    if dp_table is not None:
        out.append(f"#define {c_identifier(dp_table)} {name}_dp_table\n")
    out.append("#endif\n")
    return "".join(out)


def data_header(solver, result, table: OutputTable, keys, inputs, found=None) -> str:
    """<name>_data.h: the constants of one export."""
    plan = solver.plan
    engine = solver._engine
    out = [f"/* The constants of the model {plan.model.name}, exported by fccgen "
           f"{__version__}.\n * Generated file; do not edit. */\n",
           c_data.engine_constants(solver), method_constants(plan)]
    basis = np.asarray(getattr(engine, "start_basis", None) if
                       getattr(engine, "start_key", None) is not None else [], float)
    n_track = int(getattr(engine, "start_n_track", 0) or 0) if basis.size else 0
    out += [c_data.define("N_TRACK", n_track),
            c_data.c_array("double", "WATCH_BASIS", basis.ravel()[:n_track * plan.n_q]),
            c_data.define("N_Q_ALLOC", max(plan.n_q, 1))]
    q0, v0 = result_state(result, plan)
    out += [c_data.c_array("double", "Q0", q0), c_data.c_array("double", "V0", v0)]
    # parameters
    ptr, slots, slopes = [0], [], []
    for _, _, slope in keys:
        nz = np.flatnonzero(slope)
        slots += list(nz)
        slopes += list(slope[nz])
        ptr.append(len(slots))
    out += [c_data.define("N_KEYS", len(keys)), c_data.define("N_KEYS_ALLOC", max(1, len(keys))),
            c_data.c_strings("KEY_NAMES", [k for k, _, _ in keys]),
            c_data.c_array("double", "KEY_BASE", [x for _, x, _ in keys]),
            c_data.c_array("int", "KEY_RULE", [key_rule(k) for k, _, _ in keys]),
            c_data.c_array("int", "KEY_PTR", ptr), c_data.c_array("int", "KEY_SLOT", slots),
            c_data.c_array("double", "KEY_SLOPE", slopes)]
    # inputs: (name, start, parameter slots)
    iptr, islots = [0], []
    for _, _, s in inputs:
        islots += list(s)
        iptr.append(len(islots))
    out += [c_data.define("N_INPUTS", len(inputs)),
            c_data.define("N_INPUTS_ALLOC", max(1, len(inputs))),
            c_data.c_strings("INPUT_NAMES", [n for n, _, _ in inputs]),
            c_data.c_array("double", "INPUT_START", [x for _, x, _ in inputs]),
            c_data.c_array("int", "INPUT_PTR", iptr), c_data.c_array("int", "INPUT_SLOT", islots)]
    # outputs
    out += [c_data.define("N_DRIVER_OUT", sum(k == DRIVER for _, k, _ in table.columns)),
            c_data.define("N_OUTPUTS", len(table.columns)),
            c_data.define("N_OUTPUTS_ALLOC", max(1, len(table.columns))),
            c_data.c_strings("OUT_NAMES", [n for n, _, _ in table.columns]),
            c_data.c_array("int", "OUT_KIND", [k for _, k, _ in table.columns]),
            c_data.c_array("int", "OUT_INDEX", [i for _, _, i in table.columns]),
            c_data.c_array("int", "TRIPLE_Q", [q for q, _ in table.triples]),
            c_data.c_array("double", "TRIPLE_C", [x for _, c in table.triples for x in c]),
            c_data.c_array("int", "FRAMES", [x for f in table.frames for x in f]),
            c_data.define("N_ANGLES", len(table.angles)),
            c_data.define("N_ANGLES_ALLOC", max(1, len(table.angles))),
            c_data.c_array("int", "ANGLE_FRAMES",
                           [x for j in table.angles for x in (j["frame_a"], j["frame_b"])]),
            c_data.c_array("double", "ANGLE_X", [x for j in table.angles for x in j["x"]]),
            c_data.c_array("double", "ANGLE_A", [x for j in table.angles for x in j["a"]]),
            c_data.c_array("double", "ANGLE_N1", [x for j in table.angles for x in j["n1"]]),
            c_data.c_array("double", "ANGLE_SHIFT", [j["shift"] for j in table.angles]),
            c_data.define("N_SLIDES", len(table.slides)),
            c_data.define("N_SLIDES_ALLOC", max(1, len(table.slides))),
            c_data.c_array("int", "SLIDES",
                           [x for j in table.slides for x in (j["a"], j["b"], j["axis"])])]
    out.append(c_events.event_header(solver))
    out.append(c_sens.data(found, keys, solver))
    return "".join(out)


def key_rule(key: str) -> int:
    field = re.sub(r"\[\d+\]$", "", key).rsplit(".", 1)[-1]
    return RULES.get(field, 0)


def result_state(result, plan):
    """The run's initial state (q, v) from its first row."""
    names = [f"{n}.{c}" for n, _ in plan.triples for c in "xyz"]
    q0 = np.array([result.columns[n][0] for n in names])
    v0 = np.array([result.columns[n.rsplit(".", 1)[0] + ".v" + n[-1]][0] for n in names])
    return q0, v0


def golden_header(result, table: OutputTable) -> str:
    """selftest's rows: GOLDEN_ROWS rows of every column, spread over the run."""
    n = len(result.t)
    rows = sorted({int(round(k * (n - 1) / (GOLDEN_ROWS - 1))) for k in range(GOLDEN_ROWS)})
    names = [c for c, _, _ in table.columns]
    values = np.array([result.columns[c][r] for r in rows for c in names], float)
    # a value the run could not give (an angle whose turns its records lost) is NaN
    # there and must be NaN in the replay: marked, and written as 0
    unknown = np.isnan(values)
    return (c_data.define("N_GOLDEN", len(rows))
            + c_data.c_array("double", "GOLDEN_T", [result.t[r] for r in rows])
            + c_data.c_array("double", "GOLDEN", np.where(unknown, 0.0, values))
            + c_data.c_array("int", "GOLDEN_NAN", unknown.astype(int)))


def export_columns(solver, result) -> list[str]:
    """The result columns the export computes: all of simulate's but LEFT_OUT's."""
    from ..mechanism.driver_forces import driver_rows
    from ..model.cables import node_names
    from .c_outputs import exported_drivers
    drivers = set(driver_rows(solver.plan)) - set(exported_drivers(solver.plan))
    lowering = getattr(solver.plan.model, "mechanism", None)
    reactions = set()
    if lowering is not None:
        from ..mechanism.reaction_bases import COMPONENTS
        reactions = {f"{jl.joint.name}.{c}" for jl in lowering.joints for c in COMPONENTS}
    members = {f"{node}.{c}" for m in solver.plan.model.cables.values()
               for node in node_names(m.name, m.elements) for c in ("strain", "curvature")}
    return [n for n in result.names[1:]
            if n not in drivers and n not in reactions and n not in members]


@dataclass
class Project:
    """The files of a model's C project and what they hold."""
    name: str
    files: dict
    columns: list
    keys: list
    inputs: list
    t_end: float
    output_dt: float
    sensitivities: list = None     # the keys with sensitivities (None: exported without)
    event_names: list = None       # the model's events, NAME_event_name's order
    forces: list = None            # the driver-force columns (no sensitivity)


def c_project_files(model_path, build_dir="generated", *, progress=None,
                    sensitivities: bool = False, event_location="steps") -> Project:
    """Build the model (sparse path), run it in Python, and render its C project
    (sensitivities: with the d/dp kernels and every exported key's sensitivity;
    event_location: the project's default way of locating events, simulate's)."""
    from ..runtime.event_settings import check_event_location
    try:
        check_event_location(event_location, True if sensitivities else None)
    except ValueError as exc:
        raise ExportError(str(exc)) from None
    import fccgen
    from ..api import plan_model
    plan = plan_model(model_path)
    why = refusal(plan)
    if not why and sensitivities and plan.model.simulate.method != "rk4":
        why = (f"its simulate: method is {plan.model.simulate.method}; the export "
               "carries sensitivities through rk4 runs only (export it without "
               "--sensitivities, or with simulate: {method: rk4})")
    if why:
        raise ExportError(f"{plan.model.source}: cannot export {plan.model.name}: {why}")
    solver = fccgen.load(model_path, build_dir, linear_solver="sparse", progress=progress)
    why = refusal(solver.plan)
    if why:
        raise ExportError(f"{solver.plan.model.source}: cannot export "
                          f"{solver.plan.model.name}: {why}")
    name = c_identifier(solver.plan.model.name)
    result = python_run(solver, event_location)
    table = OutputTable(solver.plan, export_columns(solver, result))
    table.set_angle_shifts(result)
    keys = keep_initial_speeds(solver, parameter_map(solver.plan), result)
    keys = c_events.keys_keeping_constants(solver.plan, keys, solver.events_module)
    inputs = model_inputs(solver.plan)
    found = sens_result = None
    if sensitivities:
        found = c_sens.check(solver, keys, ExportError)
        sens_result = c_sens.golden_run(solver, found)
    files = render_files(solver, name, result, table, keys, inputs, found, sens_result,
                         event_location == "interpolant")
    if found is not None:
        dp = c_sens.files(solver, build_dir, progress)
        files["dp_kernels.c"] = dp["dp_kernels.c"]
        files["dp_kernels.h"] = f'#include "{name}_names.h"\n' + dp["dp_kernels.h"]
    kernels = Path(solver.module.__file__).resolve().parent
    files = {**engine_files(name), **files, **c_events.event_files(solver), "kernels.c": (kernels / "kernels.c").read_text(),
             "kernels.h": (kernels / "kernels.h").read_text()}
    d = solver.plan.model.simulate
    return Project(name, files, [c for c, _, _ in table.columns], keys, inputs,
                   float(d.t_end), float(d.output_dt if d.output_dt is not None else d.dt),
                   None if found is None else [k for k, _, _ in found],
                   [] if solver.events_module is None
                   else list(solver.events_module.EVENT_NAMES),
                   [c for c, kind, _ in table.columns if kind == DRIVER])


def export_c(model_path, out_dir, build_dir="generated", *, progress=None,
             sensitivities: bool = False, event_location="steps") -> Path:
    """Write the C project of the model into out_dir (made, or replaced when it holds
    an earlier export); returns out_dir. sensitivities: the project carries rk4
    sensitivities (docs/export.md "Sensitivities"); event_location: its default way of
    locating events ("steps" or "interpolant", docs/export.md "Step time")."""
    out_dir = Path(out_dir)
    project = c_project_files(model_path, build_dir, progress=progress,
                              sensitivities=sensitivities, event_location=event_location)
    write_project(out_dir, project.files)
    return out_dir


def keep_initial_speeds(solver, keys, result):
    """The keys, or none when moving them changes the initial speeds (an M-weighted
    projection of given speeds): the export starts from the speeds it stored."""
    if not keys:
        return keys
    q0, v0 = result_state(result, solver.plan)
    if not np.any(v0):
        return keys
    moved = solver.with_parameters({k: x0 * (1 + 1e-3) + (x0 == 0) for k, x0, _ in keys})
    v1 = moved.initial_state().v
    if np.max(np.abs(v1 - v0)) <= 1e-12 * max(1.0, float(np.max(np.abs(v0)))):
        return keys
    return []


def model_inputs(plan) -> list:
    """(name, start value, parameter slots) of the model's inputs."""
    from ..runs.inputs import input_slots
    slots = input_slots(plan)
    return [(name, float(x0), slots[name]) for name, x0 in plan.model.inputs.items()]


def render_files(solver, name, result, table, keys, inputs, found=None,
                 sens_result=None, on_interpolant=False) -> dict[str, str]:
    from ..render import table_symbol
    env = environment()
    ctx = dict(n=name, version=__version__, table=table_symbol(name),
               events=solver.events_module is not None,
               events_table=c_events.table_symbol(solver.plan.model.name),
               left_out=LEFT_OUT, keys=[k for k, _, _ in keys],
               inputs=[i for i, _, _ in inputs],
               outputs=[c for c, _, _ in table.columns], n_steps=None,
               sens_keys=None if found is None else [k for k, _, _ in found],
               dp_table=c_sens.table_symbol(solver.plan.model.name),
               on_interpolant=bool(on_interpolant),
               method=solver.plan.model.simulate.method)
    files = {f"{name}.h": env.get_template("api.h.jinja").render(ctx),
             f"{name}_api.c": env.get_template("api.c.jinja").render(ctx),
             f"{name}_data.h": data_header(solver, result, table, keys, inputs, found),
             f"{name}_golden.h": golden_header(result, table) + (
                 "" if found is None else c_sens.golden(sens_result, found, table)),
             f"{name}_names.h": names_header(
                 name, table_symbol(name), None if solver.events_module is None else
                 c_events.table_symbol(solver.plan.model.name),
                 None if found is None else c_sens.table_symbol(solver.plan.model.name)),
             "example.c": env.get_template("example.c.jinja").render(ctx),
             "selftest.c": env.get_template("selftest.c.jinja").render(ctx),
             "Makefile": env.get_template("Makefile.jinja").render(ctx),
             "CMakeLists.txt": env.get_template("CMakeLists.txt.jinja").render(ctx),
             "README.md": env.get_template("README.md.jinja").render(ctx)}
    return files


def engine_files(name: str) -> dict[str, str]:
    """The engine's sources, each header that opens the chain including the names."""
    files = {}
    for path in sorted(ENGINE.glob("*.[ch]")) + [RUNTIME / "fccgen_model.h",
                                                  RUNTIME / "fccgen_events.h"]:
        text = path.read_text()
        if path.suffix == ".h":
            text = f'#include "{name}_names.h"\n' + text
        files[path.name] = text
    return files


def write_project(out_dir: Path, everything: dict) -> None:
    """Write every file into a fresh folder next to out_dir, then put it in place."""
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = out_dir.with_name(out_dir.name + ".partial")
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    for fname, text in everything.items():
        (tmp / fname).write_text(text)
    if out_dir.exists():
        if not (out_dir / "Makefile").exists() and any(out_dir.iterdir()):
            shutil.rmtree(tmp)
            raise ExportError(f"{out_dir} exists and is not an fccgen export: give a new "
                              "or empty folder")
        shutil.rmtree(out_dir)
    tmp.rename(out_dir)
