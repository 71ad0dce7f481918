"""A model file cannot run code: text that would close the comment the generated C
puts an expression in, and compile what follows into the module, is refused.

The payload of each case is a C constructor function that, were it compiled into the
model's module, would create a marker file when the module is loaded. The model must
be refused when it is read (a ModelError naming file, line, item and rule), nothing is
built, and the marker never appears.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest
import yaml

import fccgen
from fccgen.errors import ModelError
from fccgen.model import load_model

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def payload(marker: Path) -> str:
    """An expression that closes the C block comment it is pasted into, defines a
    constructor that creates ``marker``, and opens a comment again."""
    return ('0.1*t # */ __attribute__((constructor)) static void fcc_pwn(void) '
            '{ extern int system(const char *); system(\\"touch ' + str(marker)
            + '\\"); } /*')


def attacked_model(tmp_path: Path, where: str) -> tuple[Path, Path]:
    marker = tmp_path / "PWNED"
    text = (EXAMPLES / "four_bar_driven.yaml").read_text()
    attack = payload(marker)
    if where == "driver":
        text = text.replace('angle: "10*t"', f'angle: "{attack}"')
    else:
        text += f'loads:\n  - {{type: torque, body: crank, value: [0, 0, "{attack}"]}}\n'
    path = tmp_path / "attack.yaml"
    path.write_text(text)
    return path, marker


@pytest.mark.parametrize("where, item", [("driver", "drivers[0].angle"),
                                         ("load", "loads[0].value[2]")])
def test_comment_in_an_expression_cannot_inject_code(tmp_path, where, item):
    path, marker = attacked_model(tmp_path, where)
    build = tmp_path / "generated"
    with pytest.raises(ModelError) as err:
        fccgen.load(path, build)
    assert err.value.item == item
    assert err.value.file == str(path) and err.value.line is not None
    assert "comment" in err.value.rule
    assert not marker.exists()
    assert not build.exists() or not any(build.rglob("*.c"))


# -- the whole class, in every place a model file's text can go --------------------------
# Each can end a C comment or string, splice or end a line, start a preprocessor line
# or a Python comment, end a Python string or docstring, or name another file.
HOSTILE = ["*/", "/*", "//", "\n", "\r", "\\", "??/", "#", "'", '"', '"""', "\0",
           "\u00e9", "\u2028", "{{ 7*7 }}", "{% raw %}", "../", "$(id)"]
HOSTILE_IDS = ["close", "open", "line-comment", "lf", "cr", "backslash", "trigraph",
               "hash", "quote", "dquote", "docstring", "nul", "e-acute", "u2028",
               "jinja", "jinja-block", "parent", "shell"]

RICH = """\
name: rich
gravity: [0, -9.81, 0]
bodies:
  crank: {mass: 0.2, center: [0.05, 0, 0], inertia: [1.0e-5, 1.0e-4, 1.0e-4]}
  arm: {mass: 0.5, center: [0.1, -0.1, 0], inertia: [1.0e-5, 1.0e-3, 1.0e-3]}
joints:
  - {name: O, type: revolute, bodies: [ground, crank], at: [0, 0, 0], axis: [0, 0, 1]}
  - {name: A, type: revolute, bodies: [crank, arm], at: [0.1, 0, 0], axis: [0, 0, 1],
     limits: [-1.0, 1.0]}
drivers:
  - {name: motor, joint: O, angle: "DRIVER"}
loads:
  - {type: torque, body: arm, value: [0, 0, "0.01*sin(t) - 0.1*A.rate"]}
events:
  - {name: quarter, when: "A.angle >= 0.5", do: log}
simulate: {t_end: 0.1, dt: 1.0e-3, method: rk4}
"""


def rich_models(folder: Path) -> dict[str, str]:
    (folder / "profile.csv").write_text("t, angle\n0, 0\n1, 0.5\n")
    return {"expression": RICH.replace("DRIVER", "10*t"),
            "table": RICH.replace('"DRIVER"', "{table: profile.csv}")}


def text_places(data, path=()):
    """(path, kind) of every text of the parsed YAML: mapping keys and string values."""
    items = data.items() if isinstance(data, dict) else (
        enumerate(data) if isinstance(data, list) else ())
    for key, value in items:
        if isinstance(key, str):
            yield path + (key,), "key"
        if isinstance(value, str):
            yield path + (key,), "value"
        yield from text_places(value, path + (key,))


def with_text(data, path, kind, hostile, how):
    import copy
    data = copy.deepcopy(data)
    holder = data
    for key in path[:-1]:
        holder = holder[key]
    key = path[-1]
    if kind == "key":
        new = hostile if how == "replace" else key + hostile
        holder[new] = holder.pop(key)
    else:
        holder[key] = hostile if how == "replace" else holder[key] + hostile
    return data


C_TOKENS = re.compile(r'"(?:\\.|[^"\\\n])*"|/\*.*?\*/|.', re.DOTALL)
C_ESCAPES = re.compile(r'\\(?:[\\"?abfnrtv]|[0-7]{1,3})')


def c_problems(text: str) -> list[str]:
    """What in a generated C source could come from text that escaped: outside
    comments and strings anything but printable ASCII and line breaks, a backslash, a
    quote, '//', '??' or a '#' that does not start a directive line; inside comments a
    line break in a one-line comment, '/*', '??', a backslash or a character outside
    printable ASCII; inside strings anything but printable ASCII and escapes."""
    problems = []
    for m in C_TOKENS.finditer(text):
        tok = m.group()
        if tok.startswith("/*") and len(tok) >= 4:
            body = tok[2:-2]
            if "/*" in body or "??" in body or "\\" in body \
                    or any(not (" " <= c <= "~" or c == "\n") for c in body):
                problems.append(f"comment {tok[:80]!r}")
        elif tok.startswith('"') and len(tok) >= 2:
            body = C_ESCAPES.sub("", tok[1:-1])
            if "?" in body or any(not " " <= c <= "~" for c in body):
                problems.append(f"string {tok[:80]!r}")
        elif tok == "#":
            line_start = text.rfind("\n", 0, m.start()) + 1
            if text[line_start:m.start()].strip():
                problems.append(f"'#' inside a line at {m.start()}")
        elif tok in ("'", '"', "\\") or not (" " <= tok <= "~" or tok == "\n"):
            problems.append(f"{tok!r} at {m.start()}")
    code = C_TOKENS.sub(lambda m: "" if m.group()[:2] in ('/*', '"') or m.group()[:1] == '"'
                        else m.group(), text)
    for bad in ("//", "??", "*/"):
        if bad in code:
            problems.append(f"{bad!r} outside comments and strings")
    return problems


def py_problems(name: str, text: str) -> list[str]:
    """Characters outside printable ASCII and line breaks; for Python files, a syntax
    error."""
    problems = [f"{c!r}" for c in set(text) if not (" " <= c <= "~" or c == "\n")]
    if name.endswith(".py"):
        try:
            ast.parse(text)
        except SyntaxError as exc:
            problems.append(f"syntax error {exc}")
    return problems


def source_problems(sources: dict[str, str]) -> list[str]:
    out = []
    for name, text in sources.items():
        found = c_problems(text) if name.endswith((".c", ".h")) else py_problems(name, text)
        out += [f"{name}: {p}" for p in found]
    return out


_SOURCES: dict[tuple, dict[str, str]] = {}


def generated_sources(path: Path) -> dict[str, str]:
    """Every source fccgen generates for the model (kernels and events), rendered but
    not compiled; kept per model name, class keys and event functions, which determine
    the sources (they are what the build's cache key holds)."""
    import sympy

    from fccgen.api import plan_model
    plan = plan_model(path)
    key = (plan.model.name, tuple(c.key for c in plan.classes),
           sympy.srepr([(e.name, e.function) for e in plan.model.events]))
    if key not in _SOURCES:
        _SOURCES[key] = _sources(plan)
    return _SOURCES[key]


def _sources(plan) -> dict[str, str]:
    from fccgen.build import _generate, _Stopwatch
    from fccgen.derive import derive_class
    from fccgen.events.build import event_hash, print_kernels, render
    from fccgen.events.symbolic import event_system
    from fccgen.progress import Reporter
    derived = [derive_class(c) for c in plan.classes]
    sources, _, _ = _generate(plan.model.name, derived, Reporter(None, "build"),
                              _Stopwatch())
    if plan.model.events:
        system = event_system(plan)
        events = render(plan.model.name, f"{plan.model.name}_events", system,
                        [e.name for e in plan.model.events], print_kernels(system),
                        event_hash(system), ["-O2"])
        sources.update({f"events/{k}": v for k, v in events.items()})
    return sources


@pytest.fixture(scope="module")
def rich(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rich")
    return folder, {k: yaml.safe_load(v) for k, v in rich_models(folder).items()}


def test_the_rich_models_load_and_their_sources_are_clean(rich):
    """The unmodified models pass, and the checker finds nothing in their sources
    (every kind of generated file, kernels and events, is looked at)."""
    folder, models = rich
    for kind, data in models.items():
        path = folder / f"{kind}.yaml"
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        sources = generated_sources(path)
        assert {"kernels.c", "kernels.h", "module.pyx", "build_module.py",
                "events/events.c", "events/events_module.pyx"} <= set(sources)
        assert source_problems(sources) == []


@pytest.mark.parametrize("hostile", HOSTILE, ids=HOSTILE_IDS)
def test_every_text_of_a_model_file_is_refused_or_neutralised(rich, hostile):
    """Every mapping key and string value of two models (names of the model, bodies,
    joints, drivers, events; types; expressions of drivers, loads and events; a table
    path; settings), replaced by or ending in the hostile text: the model is refused
    with a ModelError naming the file, a line and the item, or, if it loads, none of
    its generated sources holds anything the text could have put there."""
    folder, models = rich
    outcomes = {"refused": 0, "loaded": 0}
    for kind, data in models.items():
        for path, what in text_places(data):
            for how in ("replace", "append"):
                case = with_text(data, path, what, hostile, how)
                file = folder / f"case_{kind}.yaml"
                file.write_text(yaml.safe_dump(case, sort_keys=False, allow_unicode=False))
                try:
                    load_model(file)
                except ModelError as err:
                    assert err.file == str(file) and err.item, str(err)
                    outcomes["refused"] += 1
                    continue
                outcomes["loaded"] += 1
                problems = source_problems(generated_sources(file))
                assert problems == [], (path, how, problems)
    assert outcomes["refused"] > 50, outcomes


# -- the templates, given hostile text directly (the loader bypassed) ------------------
def rendered_with(text: str) -> dict[str, str]:
    """The kernel and event sources of a model one of whose classes carries ``text``
    as its function, with ``text`` as the name of an event and of an event quantity;
    the carrier class's name (a hash of its key) is written ``CARRIER``."""
    from types import SimpleNamespace

    from fccgen.build.compile import link_args
    from fccgen.events.build import render as render_events
    from fccgen.plan.classes import ElementClass
    from fccgen.printing import PrintedClass, print_class
    from fccgen.render import render_sources
    from test_printing import unit_vector_class
    printed = print_class(unit_vector_class())
    carrier = PrintedClass(ElementClass("driver_angle", (), (True, False, False),
                                        frozenset(), text), printed.kernels)
    sources = render_sources("m", "0" * 64, [printed, carrier], ["-O2"], link_args())
    system = SimpleNamespace(q=(), p=(), quantities=[SimpleNamespace(name=text)])
    events = render_events("m", "m_events", system, [text, "other"], [], "0" * 64,
                           ["-O2"])
    sources.update({f"events/{k}": v for k, v in events.items()})
    return {k: v.replace(carrier.name, "CARRIER") for k, v in sources.items()}


@pytest.mark.parametrize("hostile", HOSTILE + ["".join(HOSTILE)],
                         ids=HOSTILE_IDS + ["all"])
def test_templates_neutralise_text_they_are_given(hostile):
    """Text that reached the templates anyway would stay inside its comment or
    literal: the sources hold none of the class's sequences, only the lines that show
    the text differ from a harmless one's, and the Python literals read back as the
    text itself."""
    text = f"0.1*t {hostile} system(x) {hostile}"
    bad, good = rendered_with(text), rendered_with("0.1*t")
    assert source_problems(bad) == []
    for name in bad:
        changed = [(a, b) for a, b in zip(bad[name].splitlines(),
                                          good[name].splitlines()) if a != b]
        assert len(bad[name].splitlines()) == len(good[name].splitlines()), name
        for line, _ in changed:
            if name.endswith((".c", ".h")):
                # a comment line: the class's description or the events' names
                assert line.lstrip().startswith(("/*", "*")) and "system(x)" in line, line
            elif "system(x)" in line:
                assert holds(ast.literal_eval(line.split(" = ", 1)[1]), text), line


def holds(value, text: str) -> bool:
    """``value`` (a literal read back) holds ``text`` itself: as a string, or as the
    function of a class key (JSON)."""
    import json
    if isinstance(value, (list, tuple)):
        return any(holds(v, text) for v in value)
    if value == text:
        return True
    return isinstance(value, str) and value.startswith("{") \
        and json.loads(value).get("function") == text


def test_names_that_are_not_identifiers_never_reach_a_template():
    from fccgen.build.store import model_dir
    from fccgen.render.escape import c_identifier
    for hostile in HOSTILE:
        with pytest.raises(ValueError, match="not an ASCII C identifier"):
            c_identifier(f"m{hostile}")
        with pytest.raises(ValueError):
            model_dir(Path("generated"), f"m{hostile}")
    with pytest.raises(ValueError):
        c_identifier("m\u00e9")                   # str.isidentifier() says yes
