"""``fccgen export model.yaml --fmu FILE.fmu``: an FMI 2.0 co-simulation FMU for
linux64 with its sources inside (docs/export.md).

The FMU is the C project of :mod:`fccgen.export.c_project` plus an FMI 2.0 layer
(``<name>_fmu.c`` over the model's C API, ``fccgen_fmi2.h`` with the types and
function declarations written from the FMI 2.0 standard) and ``modelDescription.xml``.
Its variables: the outputs are the export's result columns (those of fccgen simulate but
the joint reactions, and the driver forces the export leaves out), the parameters the
with_parameters keys the export can set, the inputs the model file's ``inputs:``, for a
model with events the event outputs of :mod:`fccgen.export.fmu_events`, and for an FMU
exported with sensitivities the outputs ``d(COLUMN)/d(KEY)`` of
:mod:`fccgen.export.fmu_sens`. The shared library is built with the system C compiler in
a subprocess (cwd: a fresh folder; the compiler's output is shown when it fails) and
cached by the hash of its sources.
"""
from __future__ import annotations

import hashlib
import re
import shutil
import subprocess
import time
import uuid
import zipfile
from pathlib import Path
from xml.sax.saxutils import escape

from ..version import __version__
from ..errors import BuildError
from ..runtime._events import ACTIONS
from .c_project import ExportError, c_project_files, environment
from .fmu_events import DECLARED, EVENT_OUTPUTS, clash, enumeration_items
from .fmu_sens import chosen_keys, per_key_rows, sensitivity_outputs

# what a variable name of the FMU may be: the result columns and parameter keys are
# item names (identifiers) joined by dots, with [k] components
VARIABLE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*|\[\d+\])*")
CFLAGS = ["-std=c99", "-O2", "-fPIC", "-Wall", "-Wextra", "-pedantic"]


def xml_attribute(text: str) -> str:
    """Text XML-escaped for a double-quoted attribute."""
    return escape(text, {'"': "&quot;"})


def xml_name(name: str) -> str:
    """A variable name checked against VARIABLE_NAME (never mended), XML-escaped."""
    if not isinstance(name, str) or not VARIABLE_NAME.fullmatch(name):
        raise ValueError(f"{name!r} cannot be an FMU variable name")
    return xml_attribute(name)


def sens_variable_name(out) -> str:
    """An FMU sensitivity output's name, d(COLUMN)/d(KEY) (fmu_sens), with both parts
    checked against VARIABLE_NAME (never mended), XML-escaped."""
    xml_name(out.column)
    xml_name(out.key)
    return xml_attribute(out.name)


def model_description(ctx: dict, columns, keys, inputs, t_end, output_dt,
                      event_names=(), sens_outputs=()) -> str:
    """modelDescription.xml: outputs, parameters, inputs, the event outputs (a model
    with events: fmu_events), then the sensitivities' outputs (fmu_sens), in
    value-reference order."""
    variables = []
    for k, name in enumerate(columns):
        variables.append(dict(name=xml_name(name), vr=k, causality="output",
                              variability="continuous", initial=None, start=None))
    for k, (key, x0, _) in enumerate(keys):
        variables.append(dict(name=xml_name(key), vr=len(columns) + k, causality="parameter",
                              variability="fixed", initial="exact", start=repr(float(x0))))
    for k, (name, x0, _) in enumerate(inputs):
        variables.append(dict(name=xml_name(name), vr=len(columns) + len(keys) + k,
                              causality="input", variability="continuous", initial=None,
                              start=repr(float(x0))))
    types = {}
    if event_names:
        types = {t: [(xml_attribute(item), value) for item, value in items]
                 for t, items in enumeration_items(event_names, ACTIONS).items()}
        for v in EVENT_OUTPUTS:
            variables.append(dict(name=xml_name(v.name), vr=len(variables),
                                  causality="output", variability="discrete", initial=None,
                                  start=None, type=v.type, declared=DECLARED.get(v.field),
                                  description=xml_attribute(v.description)))
    for out in sens_outputs:
        variables.append(dict(name=sens_variable_name(out), vr=len(variables),
                              causality="output", variability="continuous", initial=None,
                              start=None, description=xml_attribute(out.description)))
    for v in variables:
        v.setdefault("type", "Real")
        v.setdefault("declared", None)
        v.setdefault("description", None)
    outputs = [k + 1 for k, v in enumerate(variables) if v["causality"] == "output"]
    return environment().get_template("modelDescription.xml.jinja").render(
        **ctx, variables=variables, outputs=outputs, types=types,
        t_end=repr(float(t_end)), output_dt=repr(float(output_dt)),
        date=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()))


def guid_of(files: dict) -> str:
    digest = hashlib.sha256()
    for name in sorted(files):
        if name not in ("README.md",):
            digest.update(name.encode() + b"\0" + files[name].encode() + b"\0")
    return "{" + str(uuid.UUID(digest.hexdigest()[:32])) + "}"


def build_library(name: str, files: dict, cache_root: Path) -> Path:
    """The FMU's shared library, from the cache when its sources are unchanged."""
    digest = hashlib.sha256()
    for fname in sorted(files):
        digest.update(fname.encode() + b"\0" + files[fname].encode() + b"\0")
    digest.update(" ".join(CFLAGS).encode())
    key = digest.hexdigest()[:16]
    target = cache_root / key / f"{name}.so"
    if target.exists():
        return target
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        raise BuildError("building an FMU needs a C compiler (cc or gcc on the PATH)")
    work = cache_root / f"{key}.partial"
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    for fname, text in files.items():
        (work / fname).write_text(text)
    sources = sorted(f for f in files if f.endswith(".c") and f not in ("example.c",
                                                                         "selftest.c"))
    cmd = [cc, *CFLAGS, "-shared", "-I.", *sources, "-o", f"{name}.so", "-lm"]
    done = subprocess.run(cmd, cwd=work, capture_output=True, text=True)
    if done.returncode != 0:
        raise BuildError(f"the FMU of {name} did not compile ({' '.join(cmd)}):\n"
                         f"{done.stdout}{done.stderr}")
    work.rename(cache_root / key)
    return target


def export_fmu(model_path, fmu_path, build_dir="generated", *, progress=None,
               sensitivities=None, event_location="steps") -> Path:
    """Write the FMU of the model to fmu_path (.fmu); returns its path.
    sensitivities: None (without), True (every key that has one) or the keys whose
    sensitivities the FMU outputs (docs/export.md, "Sensitivities in the FMU")."""
    fmu_path = Path(fmu_path)
    if fmu_path.suffix != ".fmu":
        raise ExportError(f"{fmu_path}: an FMU file name ends in .fmu")
    project = c_project_files(model_path, build_dir, progress=progress,
                              sensitivities=bool(sensitivities),
                              event_location=event_location)
    sens_keys = chosen_keys(model_path, project, sensitivities)
    name, files = project.name, dict(project.files)
    events = project.event_names or []
    taken = clash(events, [*project.columns, *(k for k, _, _ in project.keys),
                           *(i for i, _, _ in project.inputs)])
    if taken:
        raise ExportError(f"{model_path}: the FMU's event output {taken} is already a "
                          "variable of the model (rename the item that makes it)")
    env = environment()
    forces = project.forces or ()
    sens_rows = per_key_rows(project.columns, bool(events), forces)
    sens_outputs = sensitivity_outputs(project.columns, sens_keys, bool(events), forces)
    ctx = dict(n=name, version=__version__, has_events=bool(events),
               event_outputs=[v.field for v in EVENT_OUTPUTS],
               event_integer=[v.type != "Real" for v in EVENT_OUTPUTS], actions=list(ACTIONS),
               sens_keys=sens_keys, sens_rows=sens_rows)
    files["fccgen_fmi2.h"] = env.get_template("fmi2.h.jinja").render(ctx)
    guid = guid_of({**files, f"{name}_fmu.c": env.get_template("fmu.c.jinja").render(
        {**ctx, "guid": ""})})
    ctx["guid"] = guid
    files[f"{name}_fmu.c"] = env.get_template("fmu.c.jinja").render(ctx)
    library = build_library(name, files, Path(build_dir) / "fmu")
    description = model_description(ctx, project.columns, project.keys, project.inputs,
                                     project.t_end, project.output_dt, events, sens_outputs)
    fmu_path.parent.mkdir(parents=True, exist_ok=True)
    tmp = fmu_path.with_name(fmu_path.name + ".partial")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", description)
        z.write(library, f"binaries/linux64/{name}.so")
        for fname in sorted(files):
            z.writestr(f"sources/{fname}", files[fname])
    tmp.replace(fmu_path)
    return fmu_path
