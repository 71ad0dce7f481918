"""The C engine without Python: a program built from a model's generated kernels and
the engine's C sources alone (no Python, no LAPACK, tests/c/engine_threads.c).

The four-bar on the sparse path: its constants (the model's element indices and
parameters, the sparse pattern the set-up chose) are written into a header from the
Python build's engine, and the program runs RK4 with projection on three instances of
them: one alone, then two at once in two threads. Shown here:

* reentrancy: the two concurrent runs give the same bits as the run alone (each
  instance is its own struct; the model and the pattern are shared read-only);
* the same engine as the Python build: every record equals the Python-wrapped run's
  to 1e-12 relative (the same arithmetic in the same order; only the compilers'
  flags differ, and a compiler may fuse a multiply and an add on some processors);
* no heap allocation while a run steps: the program wraps malloc, calloc, realloc and
  free at link time and counts each thread's calls from the run's start to its end;
* an engine without LAPACK asked for the dense path returns an error, not a crash;
* the engine's sources compile clean as C99 (-std=c99 -Wall -Wextra -pedantic -Werror)
  and every external symbol they define starts with fcc_ (a build can rename them).
"""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import EXAMPLES

import fccgen
from fccgen import rank as rank_rule
from fccgen.render import table_symbol

RUNTIME = Path(fccgen.__file__).resolve().parent / "runtime"
ENGINE = RUNTIME / "engine"
PROGRAM = Path(__file__).resolve().parent / "c" / "engine_threads.c"
CC = shutil.which("cc") or shutil.which("gcc")
DT, N_STEPS, EVERY = 1e-3, 300, 10

pytestmark = pytest.mark.skipif(CC is None or not sys.platform.startswith("linux"),
                                reason="needs a C compiler and GNU ld (Linux)")


def c_array(ctype: str, name: str, values) -> str:
    """A static const C array (one dummy entry when empty: C has no empty arrays);
    doubles as hexadecimal literals, exact."""
    values = list(values)
    text = [float(x).hex() if ctype == "double" else str(int(x)) for x in values] or ["0"]
    return f"static const {ctype} {name}[] = {{{', '.join(text)}}};\n"


def model_header(solver, q0, v0) -> str:
    """model_data.h: the constants of the solver's model and sparse pattern, its
    tolerances and decided rank, and the run's start and steps."""
    inst = solver._asm.instance_arrays()
    engine = solver._engine
    pat = engine.pattern_arrays()
    out = [f"#define TABLE {table_symbol(solver.plan.model.name)}\n",
           f"#define N_Q {inst['n_q']}\n#define N_EL {len(inst['class_of'])}\n",
           f"#define N_BODIES {len(inst['body_elements'])}\n",
           f"#define N_TIME {len(inst['time_slots'])}\n"]
    for ctype, name, key in (("int", "CLASS_OF", "class_of"), ("int", "Q_PTR", "q_ptr"),
                             ("int", "Q_IDX", "q_idx"), ("int", "P_PTR", "param_ptr"),
                             ("int", "BODY_ELEMENTS", "body_elements"),
                             ("int", "TIME_SLOTS", "time_slots"),
                             ("double", "PARAMS", "params")):
        out.append(c_array(ctype, name, inst[key]))
    view = pat["view"]
    out.append(f"#define HAS_VIEW {int(view is not None)}\n")
    if view is not None:
        out.append(f"#define N_PINNED {len(view['pinned'])}\n"
                   f"#define N_FIXED_ROWS {len(view['fixed_rows'])}\n"
                   f"#define N_FIXED {len(view['fixed_off'])}\n")
        for key in ("snq", "sloc", "sng", "srloc", "pinned", "fixed_rows", "fixed_off"):
            out.append(c_array("int", key.upper(), view[key]))
        for key in ("efix", "fixed_norm", "fixed_g_tol", "fixed_val", "fixed_tol"):
            out.append(c_array("double", key.upper(), view[key]))
    guards = pat["guards"]
    out.append(f"#define N_ZERO_M {len(guards['zero_m'])}\n"
               f"#define N_ZERO_B {len(guards['zero_b'])}\n")
    for key in ("zero_m", "zero_b"):
        out.append(c_array("int", key.upper(), guards[key]))
        out.append(c_array("double", key.upper() + "_TOL", guards[key + "_tol"]))
    for key, values in pat["structure"].items():
        out.append(c_array("int", key.upper(), values))
    for name, value in (("RANK_TOL", engine.rank_tol),
                        ("POSITION_TOL", engine.position_tol),
                        ("GROW_TOL", rank_rule.GROW_TOL),
                        ("DECIDE_TOL", rank_rule.DECIDE_TOL),
                        ("AMBIGUOUS_LOW", rank_rule.AMBIGUOUS_LOW),
                        ("ROW_FLOOR", rank_rule.ROW_FLOOR),
                        ("BEYOND_QUOTIENT", engine.beyond_rank_quotient),
                        ("DT", DT), ("T_END", N_STEPS * DT)):
        out.append(f"#define {name} {float(value).hex()}\n")
    out.append(f"#define MAX_NEWTON {engine.max_newton}\n"
               f"#define RANK {engine.decided_rank}\n"
               f"#define N_STEPS {N_STEPS}\n#define EVERY {EVERY}\n")
    out.append(c_array("double", "Q0", q0) + c_array("double", "V0", v0))
    return "".join(out)


@pytest.fixture(scope="module")
def runs(build_dir, tmp_path_factory):
    """(the program's records per instance {name: (status, allocations, q, v)}, the
    Python-wrapped run's arrays)."""
    from fccgen.runtime._rk4 import simulate_rk4
    solver = fccgen.load(EXAMPLES / "four_bar.yaml", build_dir, linear_solver="sparse")
    init = solver.initial_state()
    solver.decide_rank(init.q)
    arrays, _ = simulate_rk4(solver._engine, init.q, init.v, N_STEPS * DT, DT, N_STEPS,
                             EVERY, True)
    work = tmp_path_factory.mktemp("c_engine")
    (work / "model_data.h").write_text(model_header(solver, init.q, init.v))
    kernels = Path(solver.module.__file__).resolve().parent
    exe = work / "engine_threads"
    cmd = [CC, "-std=gnu99", "-O2", "-pthread", f"-I{work}", f"-I{kernels}", f"-I{ENGINE}",
           f"-I{RUNTIME}", *sorted(map(str, ENGINE.glob("*.c"))), str(kernels / "kernels.c"),
           str(PROGRAM), "-o", str(exe),
           "-Wl,--wrap=malloc,--wrap=calloc,--wrap=realloc,--wrap=free", "-lm"]
    built = subprocess.run(cmd, cwd=work, capture_output=True, text=True)
    assert built.returncode == 0, built.stderr
    ran = subprocess.run([str(exe)], cwd=work, capture_output=True, text=True)
    assert ran.returncode == 0, ran.stderr
    instances = {}
    for line in ran.stdout.splitlines():
        words = line.split()
        if words[0] == "setup":
            instances["setup"] = [0, int(words[2]), [], []]
        elif words[0] == "dense_without_lapack":
            instances["dense"] = [int(words[1]), int(words[2]), " ".join(words[3:]), None]
        elif words[0] == "instance":
            instances[words[1]] = [int(words[3]), int(words[5]), [], []]
        elif words[0] == "record":
            n = len(words[3:]) // 2
            numbers = [float.fromhex(w) for w in words[3:]]
            instances[words[1]][2].append(numbers[:n])
            instances[words[1]][3].append(numbers[n:])
    return {k: (s, a, q if k == "dense" else np.array(q), np.array(v))
            for k, (s, a, q, v) in instances.items()}, arrays


def test_two_threads_give_the_bits_of_a_run_alone(runs):
    program, _ = runs
    assert set(program) == {"setup", "dense", "alone", "thread1", "thread2"}
    status, _, q, v = program["alone"]
    assert status == 0 and q.shape == (1 + N_STEPS // EVERY, 6)
    for name in ("thread1", "thread2"):
        assert program[name][0] == 0
        assert np.array_equal(program[name][2], q) and np.array_equal(program[name][3], v)


def test_the_program_runs_the_python_builds_engine(runs):
    """Every record of the program equals the Python-wrapped run's to 1e-12 relative:
    the same C engine with the same steps (only the compilers' flags differ)."""
    program, arrays = runs
    _, _, q, v = program["alone"]
    assert np.max(np.abs(q - arrays["q"])) <= 1e-12 * np.max(np.abs(arrays["q"]))
    assert np.max(np.abs(v - arrays["v"])) <= 1e-12 * np.max(np.abs(arrays["v"]))
    assert np.max(np.abs(arrays["v"])) > 0.1          # the linkage moved


def test_no_heap_allocation_while_stepping(runs):
    """The counter wraps every allocation call at link time (so it sees the engine's,
    whatever macro they go through); each thread counts its own, from the run's start
    to its end: 300 steps, 31 records, every projection. The same counter sees the
    instances' set-up allocate."""
    program, _ = runs
    assert [program[k][1] for k in ("alone", "thread1", "thread2")] == [0, 0, 0]
    assert program["setup"][1] > 3 * 20


def test_the_dense_path_without_lapack_is_an_error_not_a_crash(runs):
    """An engine made without a LAPACK table, asked for the dense path's accelerations:
    -1 and FCC_ERR_NO_LAPACK (8), with its sentence in the instance."""
    program, _ = runs
    rc, code, message, _ = program["dense"]
    assert (rc, code) == (-1, 8)
    assert "without a LAPACK table" in message


def test_the_engine_is_c99_and_prefixed(tmp_path):
    """-std=c99 -Wall -Wextra -pedantic -Werror, and nm: every external symbol the
    engine's objects define starts with fcc_ (a build that links two engines renames
    that one prefix)."""
    objects = []
    for source in sorted(ENGINE.glob("*.c")):
        obj = tmp_path / (source.stem + ".o")
        done = subprocess.run([CC, "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror",
                               "-O2", f"-I{RUNTIME}", f"-I{ENGINE}", "-c", str(source),
                               "-o", str(obj)], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        objects.append(str(obj))
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("no nm to list the symbols")
    listed = subprocess.run([nm, "-g", "--defined-only", *objects], capture_output=True,
                            text=True, check=True).stdout
    symbols = [line.split()[2] for line in listed.splitlines() if len(line.split()) == 3]
    assert symbols and all(s.startswith("fcc_") for s in symbols), \
        [s for s in symbols if not s.startswith("fcc_")]
