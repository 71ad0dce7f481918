"""Tune a scissor boom's hinge springs and dampers with exact gradients: latch by T,
with the smallest latch impulse.

    python examples/optimize_deployment.py [--units 4] [--t 0.45] [--min-rate 1]

The boom (examples/make_scissor_boom.py) deploys from its folded state under a torsion
spring and a rotational damper at each crossing pivot, and latches at full deployment
(the lock event `latch` on pivot X0). The design is each pivot's stiffness and damping
(2 N numbers). The goal: latch by time T, with the smallest latch impulse. The boom has
one degree of freedom and latches at a fixed angle, so the lock's impulse is the
boom's effective inertia there times the pivot's rate X0.rate just before it: the
smaller that rate, the smaller the shock. So:

    minimise   J = (w_latch / w_0)^2 + 1e-3 sum (k_i / k_0)^2     (springs no stiffer
    subject to t_latch <= T                                         than needed)
               w_latch >= w_min

with w_latch the rate at the latch, w_0 its value at the start design, and w_min the
least rate that engages the latch (1 rad/s by default). Without it the optimum is a
boom that barely reaches the latch, where its time grows without bound as the rate
goes to 0: a design no engineer would fly, and one whose latch time no derivative,
exact or differenced, describes beyond a hair's width. Each
evaluation runs the boom to its latch: the model's lock becomes a `stop` at the same
angle, so the run ends at the latch, its last row holds w_latch, and the event row
its time with d(time)/d(key) (docs/sensitivities.md, "Events").

scipy.optimize.minimize (SLSQP, bounds on k and c) runs twice from the same start:
with the exact gradients of J and of the constraints (one run with the 2 N
sensitivities per design) and with its own finite-difference gradients (2 N + 1
plain runs per design; the objective and the constraints share each run). It prints,
for each, the simulations run, the CPU time, J, the latch time and rate and the design
reached; then the latch impulse of the real latched boom at the start and at each
optimum (`result.events`' `impulse`).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

sys.path.insert(0, str(Path(__file__).resolve().parent))
import make_scissor_boom  # noqa: E402

import fccgen  # noqa: E402

DAMPING = 0.05            # N m s, each pivot's damper at the start design
REGULARISATION = 1e-3


def boom_files(units: int, folder: Path) -> tuple[Path, Path]:
    """The latched boom with a damper at each pivot's spring, and the same boom whose
    latch is a stop (the run ends at the latch)."""
    text = make_scissor_boom.model_text(units)
    lines = [ln[:-1] + f", damping: {DAMPING}}}" if "torsion_spring" in ln else ln
             for ln in text.splitlines()]
    latched = folder / "boom_latched.yaml"
    latched.write_text("\n".join(lines) + "\n")
    to_latch = folder / "boom_to_latch.yaml"
    stop = [ln.replace("do: lock, joint: X0", "do: stop") for ln in lines]
    if stop == lines:
        raise RuntimeError("make_scissor_boom's latch event changed: update this example")
    to_latch.write_text("\n".join(stop) + "\n")
    return latched, to_latch


class Problem:
    """J(design), the constraints and their gradients, counting the simulations (one
    per design and kind: the objective and the constraints at the same design share
    their run)."""

    def __init__(self, solver, T: float, w_min: float):
        self.solver, self.T, self.w_min = solver, T, w_min
        n = len(solver.plan.model.loads)
        self.n = n
        self.keys = ([f"loads[{i}].stiffness" for i in range(n)]
                     + [f"loads[{i}].damping" for i in range(n)])
        self.k0 = solver.plan.model.loads[0].stiffness
        self.runs = 0
        self._kept: dict = {}
        self.w0 = 1.0
        self.w0 = self.latch(self.start(), exact=False)[0]

    def start(self) -> np.ndarray:
        return np.array([self.k0] * self.n + [DAMPING] * self.n)

    def latch(self, design, exact: bool):
        """(w_latch, t_latch) and, when exact, their gradients over the design."""
        key = (np.asarray(design, float).tobytes(), exact)
        if key not in self._kept:
            self.runs += 1
            t_end = 3.0 * self.T
            r = self.solver.with_parameters(dict(zip(self.keys, design))).simulate(
                t_end=t_end, dt=1e-3, method="rk4", output_dt=t_end, reactions=False,
                sensitivities=self.keys if exact else None)
            rows = [e for e in r.events if e["name"] == "latch"]
            if not rows:
                # no latch by 3 T: infeasible, and J no better than at the start (the
                # optimiser steps back from it)
                zero = np.zeros(len(self.keys))
                self._kept[key] = (self.w0, t_end) + ((zero, zero) if exact else ())
            else:
                w, t = r["X0.rate"][-1], rows[0]["t"]
                out = (w, t)
                if exact:
                    out += (np.array([r.sensitivity("X0.rate", k)[-1] for k in self.keys]),
                            np.array([rows[0][f"d(time)/d({k})"] for k in self.keys]))
                self._kept[key] = out
        return self._kept[key]

    def objective(self, design, exact: bool = False):
        w = self.latch(design, exact)[0]
        k = np.asarray(design[:self.n])
        J = (w / self.w0) ** 2 + REGULARISATION * np.sum((k / self.k0) ** 2)
        if not exact:
            return J
        grad = 2 * w / self.w0 ** 2 * self.latch(design, True)[2]
        grad[:self.n] += 2 * REGULARISATION * k / self.k0 ** 2
        return J, grad

    def constraints(self, design, exact: bool = False):
        """[T - t_latch, w_latch - w_min] (both >= 0 when met)."""
        w, t = self.latch(design, exact)[:2]
        return np.array([self.T - t, w - self.w_min])

    def constraints_gradient(self, design):
        out = self.latch(design, True)
        return np.array([-out[3], out[2]])


def optimise(problem: Problem, exact: bool, bounds):
    if exact:
        con = {"type": "ineq", "fun": lambda x: problem.constraints(x, True),
               "jac": problem.constraints_gradient}
        return minimize(lambda x: problem.objective(x, True), problem.start(), jac=True,
                        method="SLSQP", bounds=bounds, constraints=[con])
    con = {"type": "ineq", "fun": problem.constraints}
    return minimize(problem.objective, problem.start(), method="SLSQP", bounds=bounds,
                    constraints=[con])


def latch_impulse(latched_solver, keys, design, T: float) -> str:
    r = latched_solver.with_parameters(dict(zip(keys, design))).simulate(
        t_end=3.0 * T, dt=1e-3, method="rk4", output_dt=3.0 * T, reactions=False)
    rows = [e for e in r.events if e["name"] == "latch"]
    return f"{rows[0]['impulse']:.4g}" if rows else f"(no latch by {3 * T:g} s)"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--units", type=int, default=4)
    ap.add_argument("--t", type=float, default=0.45, help="the latest latch time T (s)")
    ap.add_argument("--min-rate", type=float, default=1.0,
                    help="the least rate at the latch that engages it (rad/s)")
    args = ap.parse_args()
    if args.units < 1 or not args.t > 0 or not args.min_rate >= 0:
        ap.error("--units must be at least 1, --t positive and --min-rate >= 0")
    folder = Path(tempfile.mkdtemp(prefix="optimize_deployment_"))
    latched, to_latch = boom_files(args.units, folder)
    solver = fccgen.load(to_latch, folder / "generated")
    p0 = Problem(solver, args.t, args.min_rate)
    n = p0.n
    t0 = p0.latch(p0.start(), False)[1]
    bounds = [(5.0, 80.0)] * n + [(1e-3, 1.0)] * n     # c = 0 would fold the damper away
    print(f"scissor boom of {args.units} units, design: {n} stiffnesses and {n} dampings; "
          f"the start latches at {t0:.4f} s at {p0.w0:.4f} rad/s; goal: latch by "
          f"{args.t} s, slowly (at least {args.min_rate} rad/s)")
    found = {}
    for label, exact in (("exact gradient", True), ("finite differences", False)):
        p = Problem(solver, args.t, args.min_rate)
        start = time.process_time()
        out = optimise(p, exact, bounds)
        cpu = time.process_time() - start
        w, t = p.latch(out.x, False)[:2]
        found[label] = out.x
        print(f"{label}: {p.runs} simulations, {cpu:.2f} s CPU, J = {out.fun:.7g} "
              f"({out.message}); latch at {t:.5f} s at {w:.5f} rad/s")
        print("    k = " + ", ".join(f"{v:.4g}" for v in out.x[:n])
              + "; c = " + ", ".join(f"{v:.4g}" for v in out.x[n:]))
    boom = fccgen.load(latched, folder / "generated_latched")
    print("latch impulse of the latched boom: start "
          f"{latch_impulse(boom, p0.keys, p0.start(), args.t)}, "
          + ", ".join(f"{label} {latch_impulse(boom, p0.keys, x, args.t)}"
                      for label, x in found.items()))


if __name__ == "__main__":
    main()
