"""Tune a scissor boom's hinge springs and dampers with exact gradients.

    python examples/optimize_deployment.py [--units 4] [--t 0.6]

The boom (examples/make_scissor_boom.py, without its latch: runs with events do not
carry sensitivities yet) deploys from its folded state under a torsion spring and a
rotational damper at each crossing pivot. The design is each pivot's stiffness and
damping (2 N numbers). The goal: the tip at the target reach at time T, arriving slowly
(the speed at T is what a latch there would have to stop), with the springs no
stiffer than needed:

    J = ((x_tip(T) - x_target) / L)^2 + (v_tip(T) / v_ref)^2 + 1e-4 sum (k_i / k_0)^2

scipy.optimize.minimize (L-BFGS-B, bounds on k and c) runs twice from the same start:
with the exact gradient (one run with the 2 N sensitivities per evaluation,
docs/sensitivities.md) and with its own finite-difference gradient (2 N + 1 plain
runs per evaluation). It prints, for each, the simulations run, the CPU time, J and
the design reached.
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


def boom_file(units: int, folder: Path) -> Path:
    """The unlatched boom with a damper (0.05 N m s) at each pivot's spring."""
    text = make_scissor_boom.model_text(units, latch=False)
    lines = [ln[:-1] + ", damping: 0.05}" if "torsion_spring" in ln else ln
             for ln in text.splitlines()]
    path = folder / "boom.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


class Problem:
    """J(design) and its gradient, counting the simulations."""

    def __init__(self, solver, t_end: float, target: float):
        self.solver, self.t_end, self.target = solver, t_end, target
        n = len(solver.plan.model.loads)
        self.k_keys = [f"loads[{i}].stiffness" for i in range(n)]
        self.c_keys = [f"loads[{i}].damping" for i in range(n)]
        self.k0 = solver.plan.model.loads[0].stiffness
        self.tip = f"T{n}"
        self.L = make_scissor_boom.LENGTH
        self.v_ref = self.L / t_end
        self.runs = 0

    def _run(self, x, sens):
        values = dict(zip(self.k_keys + self.c_keys, x))
        self.runs += 1
        return self.solver.with_parameters(values).simulate(
            t_end=self.t_end, dt=1e-3, method="rk4", output_dt=self.t_end,
            reactions=False, sensitivities=sens)

    def _parts(self, r):
        x, v = r[f"{self.tip}.x"][-1], r[f"{self.tip}.vx"][-1]
        return x, v

    def value(self, design):
        x, v = self._parts(self._run(design, None))
        return self._objective(design, x, v)

    def _objective(self, design, x, v):
        k = np.asarray(design[:len(self.k_keys)])
        return (((x - self.target) / self.L) ** 2 + (v / self.v_ref) ** 2
                + 1e-4 * np.sum((k / self.k0) ** 2))

    def value_and_gradient(self, design):
        keys = self.k_keys + self.c_keys
        r = self._run(design, keys)
        x, v = self._parts(r)
        J = self._objective(design, x, v)
        grad = np.empty(len(keys))
        for i, key in enumerate(keys):
            dx = r.sensitivity(f"{self.tip}.x", key)[-1]
            dv = r.sensitivity(f"{self.tip}.vx", key)[-1]
            grad[i] = (2 * (x - self.target) / self.L ** 2 * dx
                       + 2 * v / self.v_ref ** 2 * dv)
        k = np.asarray(design[:len(self.k_keys)])
        grad[:len(self.k_keys)] += 2e-4 * k / self.k0 ** 2
        return J, grad


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--units", type=int, default=4)
    ap.add_argument("--t", type=float, default=0.6, help="the time T of the goal")
    args = ap.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="optimize_deployment_"))
    solver = fccgen.load(boom_file(args.units, folder), folder / "generated")
    start = solver.simulate(t_end=args.t, dt=1e-3, method="rk4", output_dt=args.t,
                            reactions=False)
    n = args.units
    reach0 = start[f"T{n}.x"][-1]
    target = reach0 + 0.5 * (reach0 - start[f"T{n}.x"][0])
    x0 = np.array([solver.plan.model.loads[0].stiffness] * n + [0.05] * n)
    bounds = [(1.0, 200.0)] * n + [(1e-3, 2.0)] * n      # c = 0 would fold the damper away
    print(f"scissor boom of {n} units: tip at T = {args.t} s starts at {reach0:.4f} m; "
          f"target {target:.4f} m; design: {n} stiffnesses and {n} dampings")
    for label, use_exact in (("exact gradient", True), ("finite differences", False)):
        p = Problem(solver, args.t, target)
        t0 = time.process_time()
        if use_exact:
            out = minimize(p.value_and_gradient, x0, jac=True, method="L-BFGS-B",
                           bounds=bounds)
        else:
            out = minimize(p.value, x0, method="L-BFGS-B", bounds=bounds)
        cpu = time.process_time() - t0
        print(f"{label}: {p.runs} simulations, {cpu:.2f} s CPU, J = {out.fun:.6g} "
              f"({out.message})")
        print("    k = " + ", ".join(f"{v:.4g}" for v in out.x[:n])
              + "; c = " + ", ".join(f"{v:.4g}" for v in out.x[n:]))


if __name__ == "__main__":
    main()
