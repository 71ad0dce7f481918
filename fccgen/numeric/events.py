"""Events in the NumPy version (docs/events.md): the state of a run's events and their
actions, written independently of the compiled runtime (fccgen/runtime/_events.pyx)
so that the two cross-check each other.

The joint rows a lock holds are added to the constrained solves as rows of the
augmented Jacobian [B; G_used] (numeric/constrained.py): accelerations, the M-
orthogonal velocity projections of impacts and the Newton correction of the held
positions after each step. Which active rows are used is decided at every switch by
the rule of fccgen.rank: on the row-scaled [B; G_active], one candidate at a time, a
row is used when it raises the rank by the SVD gap test. Impacts: a lock (and a rest)
is the M-orthogonal projection onto the new rows; a bounce is Newton's law along the
constrained response z to ds/dq, v+ = v- + mu z with mu = -(1 + e) s'- / (ds/dq . z).
A resting bounce is released where the multiplier of its row turns to pull.

The event table's rows are those of the runtime (fccgen.events.table.event_rows).
"""
from __future__ import annotations

import numpy as np

from .. import rank as rank_rule
from ..errors import SimulationError
from .constrained import RankKeeper, constrained_solve
from .event_quantities import (POINT_QUANTITIES, Triples, event_tree, event_value,
                               joint_quantity, quantity_kind)

ACTIONS = ("stop", "log", "lock", "unlock", "bounce", "rest", "release")
NOTES = {"redundant": 1, "uncertain": 2}
DIRECTIONS = {"rising": 1, "falling": -1, "either": 0}
LEAVE = 1e-300                  # a value just before a crossing (see leaving)


class NumericEvents:
    """The events of one model for one NumPy solver."""

    def __init__(self, solver, tol: float = 1e-12, rest_speed: float = 1e-6,
                 max_per_step: int = 50):
        self.solver, self.tol, self.v_rest = solver, tol, rest_speed
        self.max_per_step = max_per_step
        plan = solver.plan
        lowering = getattr(plan.model, "mechanism", None)
        self.joints = {jl.joint.name: jl.joint for jl in lowering.joints} if lowering else {}
        self.triples = Triples(plan)
        events = plan.model.events
        self.names = tuple(e.name for e in events)
        self.ne = len(events)
        self.trees = [event_tree(e.when) for e in events]
        self.direction = [DIRECTIONS[e.direction] for e in events]
        self.action = [ACTIONS.index(e.action) for e in events]
        self.restitution = [e.restitution for e in events]
        self.used_names = sorted({f"{n.value.id}.{n.attr}" for tree in self.trees
                                  for n in _attributes(tree)})
        self.quantities: dict[tuple[str, str], object] = {}
        for name in self.used_names:
            joint, what = name.split(".", 1)
            if joint in self.joints:
                self._quantity(joint, quantity_kind(self.joints[joint], what))
        self.row, self.row2 = [], []
        for e in events:
            keys = []
            if e.joint is not None and e.action in ("lock", "unlock", "bounce"):
                j = self.joints[e.joint]
                keys.append((j.name, "angle" if j.type in ("revolute", "cylindrical")
                             else "position"))
                if j.type == "cylindrical":
                    keys.append((j.name, "position"))
            rows = [self._quantity(*key) for key in keys]
            self.row.append(rows[0] if rows else -1)
            self.row2.append(rows[1] if len(rows) > 1 else -1)
        self.start(np.asarray(plan.q0, float))

    def _quantity(self, joint: str, kind: str) -> int:
        """The row of a joint quantity (made on first use)."""
        key = (joint, kind)
        if key not in self.quantities:
            self.quantities[key] = joint_quantity(self.triples, self.joints[joint], kind)
        return list(self.quantities).index(key)

    # -- state ---------------------------------------------------------------------
    def start(self, q) -> None:
        """A run's start: angle references 0, no row active or resting, no log."""
        nr = len(self.quantities)
        self.theta = np.zeros(nr)
        self.active = np.zeros(nr, bool)
        self.used = np.zeros(nr, bool)
        self.held = np.zeros(nr)
        self.rested = np.zeros(self.ne, bool)
        self.rel_sign = np.zeros(self.ne)
        self.log: list[list[float]] = []
        self.stopped = False
        self.s0 = np.zeros(2 * self.ne)
        self.keeper = RankKeeper(groups=self._groups())
        self.base_keeper = RankKeeper(groups=self.solver.row_groups)

    def refresh(self, q) -> None:
        """Move the angle references to the angles at q (turn counting)."""
        for i, quantity in enumerate(self.quantities.values()):
            self.theta[i] = quantity.value(q, self.theta[i])

    def values(self, q) -> np.ndarray:
        return np.array([x.value(q, th) for x, th in zip(self.quantities.values(),
                                                          self.theta)])

    def _groups(self) -> np.ndarray:
        base = self.solver.row_groups
        base = np.arange(self.solver.n_g) if base is None else np.asarray(base)
        return np.concatenate([base, self.solver.n_g + np.arange(int(self.used.sum()))])

    # -- event functions ---------------------------------------------------------------
    def _env(self, q, v, t) -> dict:
        n = self.solver.n_q
        zero = np.zeros(2 * n)
        env = {"t": (float(t), zero)}
        for name, value in getattr(self.solver, "input_values", {}).items():
            env[name] = (value, zero)          # the inputs: held, constant in q and v
        keys = list(self.quantities)
        for name in self.used_names:
            owner, what = name.split(".", 1)
            if owner in self.joints:
                i = keys.index((owner, quantity_kind(self.joints[owner], what)))
                x = self.quantities[keys[i]]
                if what in ("angle", "position"):
                    grad = x.gradient_rate_bias(q, v)[0]
                    env[name] = (x.value(q, self.theta[i]), np.concatenate([grad, 0 * grad]))
                else:                          # rate, speed: values only
                    env[name] = (x.gradient_rate_bias(q, v)[1], zero)
            else:
                r, dr, k = self.triples.get(owner, q, v)
                if what in POINT_QUANTITIES:
                    c = POINT_QUANTITIES[what]
                    grad = zero.copy()
                    if k is not None:
                        grad[3 * k + c] = 1.0
                    env[name] = (float(r[c]), grad)
                else:                          # vx, vy, vz: values only
                    env[name] = (float(dr[POINT_QUANTITIES[what[1]]]), zero)
        return env

    def functions(self, q, v, t) -> tuple[np.ndarray, np.ndarray]:
        """(s_k, ds_k/dq) of every event at (q, v, t)."""
        env = self._env(q, v, t)
        out = [event_value(tree, env) for tree in self.trees]
        n = self.solver.n_q
        return (np.array([s for s, _ in out]),
                np.array([g[:n] for _, g in out]).reshape(self.ne, n))

    def watch(self, q, v, t) -> np.ndarray:
        """The event functions, then per event the release function of a resting
        bounce (rel_sign mu of its row's multiplier; -1 while not resting)."""
        s = self.functions(q, v, t)[0]
        out = np.concatenate([s, -np.ones(self.ne)])
        resting = [k for k in range(self.ne) if self.rests(k) and self.rel_sign[k] != 0.0]
        if resting:
            self.solver.set_time(t)
            _, nu = self.solve(q, v, multipliers=True)
            rows = np.flatnonzero(self.used)
            for k in resting:
                pos = int(np.flatnonzero(rows == self.row[k])[0])
                out[self.ne + k] = self.rel_sign[k] * -nu[pos]
        return out

    def locked(self, k: int) -> bool:
        return (ACTIONS[self.action[k]] in ("lock", "bounce") and self.row[k] >= 0
                and bool(self.active[self.row[k]]))

    def rests(self, k: int) -> bool:
        return bool(self.rested[k]) and self.row[k] >= 0 and bool(self.active[self.row[k]])

    def crosses(self, k: int, a: float, b: float) -> bool:
        up, down = a < 0.0 <= b, a > 0.0 >= b
        d = 1 if k >= self.ne else self.direction[k]
        return up if d > 0 else down if d < 0 else (up or down)

    def watched(self, k: int, a, b) -> bool:
        """Watched value k crosses from a to b and counts (a held lock's hovering at
        zero does not)."""
        if k < self.ne:
            return self.crosses(k, a[k], b[k]) and not self.locked(k)
        return self.rests(k - self.ne) and self.crosses(k, a[k], b[k])

    def first_crossing(self, a, b) -> int:
        """The first watched value that crosses from a to b, or -1; every one that does
        is kept for ties()."""
        self._crossed = [k for k in range(2 * self.ne) if self.watched(k, a, b)]
        return self._crossed[0] if self._crossed else -1

    def ties(self, first: int, before, now) -> list:
        """The watched values other than ``first`` that crossed in the step (the last
        first_crossing) and had crossed by the instant whose values are ``now``
        (``before``: the values the step started from). After the first event acts
        and the values are read at its instant, these are past their zero there and
        would never be seen to cross: they act at the same instant
        (engine/fcc_event_locate.c, "Ties")."""
        return [k for k in getattr(self, "_crossed", ())
                if k != first and self.watched(k, before, now)]

    # -- solves with the used rows ------------------------------------------------------
    def _rows(self, q, v):
        """(G, bias) of the used rows at (q, v)."""
        keys = [x for x, u in zip(self.quantities.values(), self.used) if u]
        out = [x.gradient_rate_bias(q, v) for x in keys]
        n = self.solver.n_q
        return (np.array([g for g, _, _ in out]).reshape(len(out), n),
                np.array([b for _, _, b in out]))

    def _keeper(self, rows: bool = True) -> RankKeeper:
        """The rank keeper of solves with the used rows (rows False: B alone): the
        run's decided rank plus the used rows (their own statistics, not the run's)."""
        base = self.solver._rank.rank
        keeper = self.keeper if rows else self.base_keeper
        keeper.groups = self._groups() if rows else self.solver.row_groups
        want = -1 if base < 0 else base + (int(self.used.sum()) if rows else 0)
        if keeper.rank != want or not keeper.stats:
            keeper.decide(want)
        return keeper

    def solve(self, q, v, multipliers: bool = False):
        """The accelerations at (q, v) with the used rows held (and, with multipliers,
        the used rows' multipliers nu of M a + B^T lambda + G^T nu = f - h)."""
        s = self.solver
        if not self.used.any():
            return s.accelerations(q, v), np.zeros(0)
        a = s._assemble(q, v, ("mass_matrix", "h_vector", "applied_forces",
                               "constraint_jacobian", "constraint_bias"))
        G, bias = self._rows(q, v)
        B = np.vstack([a["constraint_jacobian"], G])
        acc = constrained_solve(a["mass_matrix"], B, a["applied_forces"] - a["h_vector"],
                                np.concatenate([-a["constraint_bias"], -bias]), s.rank_tol,
                                self._keeper())
        if not multipliers:
            return acc, np.zeros(0)
        rhs = a["applied_forces"] - a["h_vector"] - a["mass_matrix"] @ acc
        lam = np.linalg.lstsq(B.T, rhs, rcond=rank_rule.DECIDE_TOL)[0]
        return acc, lam[s.n_g:]

    def accelerations(self, q, v) -> np.ndarray:
        return self.solve(q, v)[0]

    def project_velocities(self, q, v) -> np.ndarray:
        """v projected M-orthogonally onto B v = -dg/dt and the used rows G v = 0."""
        s = self.solver
        if not self.used.any():
            return s.project_velocities(q, v)
        a = s._assemble(q, None, ("mass_matrix", "constraint_jacobian", "constraint_rate"))
        G = self._rows(q, v)[0]
        M = a["mass_matrix"]
        return constrained_solve(M, np.vstack([a["constraint_jacobian"], G]), M @ v,
                                 np.concatenate([-a["constraint_rate"], np.zeros(len(G))]),
                                 s.rank_tol, self._keeper())

    def hold(self, q, v):
        """After a step's projections: Newton on g = 0 and the used rows at their held
        values (minimum M-norm), then the velocities (:meth:`project_velocities`)."""
        s = self.solver
        if not self.used.any():
            return q, v
        q = np.array(q, float)
        M = s.mass_matrix(q)
        for _ in range(s.max_newton + 1):
            G = self._rows(q, v)[0]
            B = np.vstack([s.constraint_jacobian(q), G])
            res = np.concatenate([s.constraints(q), self.values(q)[self.used]
                                  - self.held[self.used]])
            norms = np.sqrt(np.einsum("ij,ij->i", B, B))
            if np.max(np.abs(res) / np.where(norms > 0, norms, 1.0)) <= s.position_tol:
                break
            q = q + constrained_solve(M, B, np.zeros(s.n_q), -res, s.rank_tol,
                                      self._keeper())
        return q, self.project_velocities(q, v)

    # -- switches -----------------------------------------------------------------------
    def decide(self, q) -> tuple[int, float]:
        """Which active rows enter the solves (the rank rule on the row-scaled
        [B; G_active], a candidate at a time); returns (NOTE_ bits, sigma)."""
        s = self.solver
        B = s.constraint_jacobian(q)
        Bs = B / rank_rule.row_scales(B, s.row_groups)[:, None] if B.size else B
        self.used[:] = False
        G = np.array([x.gradient_rate_bias(q, np.zeros(s.n_q))[0]
                      for x in self.quantities.values()]).reshape(-1, s.n_q)
        kept, note, sigma = Bs, 0, 0.0
        rank = _rank(kept)[0]
        for i in np.flatnonzero(self.active):
            row = G[i] / max(np.linalg.norm(G[i]), 1e-300)
            r, sv = _rank(np.vstack([kept, row]))
            ratio = (sv[r - 1] if r > rank else sv[min(rank, len(sv) - 1)]) / sv[0] \
                if sv.size and sv[0] > 0 else 0.0
            if rank_rule.AMBIGUOUS_LOW <= ratio <= rank_rule.GROW_TOL:
                note |= NOTES["uncertain"]
                sigma = ratio if sigma == 0.0 else min(sigma, ratio)
            if r > rank:
                self.used[i], kept, rank = True, np.vstack([kept, row]), r
        return note, sigma

    def _set_rows(self, k: int, on: bool, q) -> None:
        values = self.values(q)
        for row in (self.row[k], self.row2[k]):
            if row >= 0:
                self.active[row], self.held[row] = on, values[row]
        if self.row[k] >= 0:
            self.rested[[j for j in range(self.ne) if self.row[j] == self.row[k]]] = False

    def _lock(self, k, q, v):
        """Activate event k's rows at their present values; the plastic impact.
        Returns (v, impulse, notes, sigma)."""
        self._set_rows(k, True, q)
        note, sigma = self.decide(q)
        if any(r >= 0 and not self.used[r] for r in (self.row[k], self.row2[k])):
            note |= NOTES["redundant"]
        v_new = self.project_velocities(q, v)
        s = self.solver
        G = self._rows(q, v)[0]
        B = np.vstack([s.constraint_jacobian(q), G])
        nu = np.linalg.lstsq(B.T, s.mass_matrix(q) @ (v - v_new),
                             rcond=rank_rule.DECIDE_TOL)[0][s.n_g:]
        return v_new, float(np.linalg.norm(nu)), note, sigma

    def kinetic(self, q, v) -> float:
        return float(self.solver.kinetic_energy(q, v))

    def apply(self, k: int, q, v, t: float):
        """Act on watched value k at (q, v, t) (k < 0: the Zeno guard, event -1 - k
        rests; k >= ne: release of the resting bounce k - ne). Returns (q, v, done):
        done False for a bounce that does not approach its surface."""
        s = self.solver
        rest = k < 0
        k = -1 - k if rest else k
        act = "release" if k >= self.ne else ACTIONS[self.action[k]]
        k = k - self.ne if k >= self.ne else k
        s.set_time(t)
        v = self.project_velocities(q, v)
        ke0, impulse, speed, note, sigma = self.kinetic(q, v), 0.0, 0.0, 0, 0.0
        if act == "stop":
            self.stopped = True
        elif act == "lock":
            v, impulse, note, sigma = self._lock(k, q, v)
        elif act in ("unlock", "release"):
            self._set_rows(k, False, q)
            note, sigma = self.decide(q)
        elif act == "bounce":
            value, grads = self.functions(q, v, t)
            g = grads[k]
            approach = float(g @ v)
            if not rest and self.direction[k] != 0 and approach * self.direction[k] <= 0:
                return q, v, False
            speed = approach
            if not rest:                       # the Zeno guard rests without it
                v, impulse = self._bounce(k, q, v, g, approach)
            if (rest or abs(approach) < self.v_rest) and self.row[k] >= 0:
                act = "rest"                   # too slow to go on: the limit holds
                v, impulse, note, sigma = self._lock(k, q, v)
                self._rest_sign(k, q, g, approach)
        self.log.append([t, k, ACTIONS.index(act), impulse, ke0, self.kinetic(q, v),
                         self._error(q), s.n_q - max(s._rank.rank, 0) - int(self.used.sum()),
                         speed, note, sigma])
        return q, v, True

    def _bounce(self, k, q, v, g, approach):
        """Newton's law along the constrained response z to g = ds_k/dq."""
        s = self.solver
        B = s.constraint_jacobian(q)
        if self.used.any():
            B = np.vstack([B, self._rows(q, v)[0]])
        z = constrained_solve(s.mass_matrix(q), B, g, np.zeros(len(B)), s.rank_tol,
                              self._keeper())
        gz = float(g @ z)
        if not gz > 0.0:
            raise SimulationError(f"event {self.names[k]!r}: the bounce's direction is "
                                  "held by the constraints (no constrained response)")
        mu = -(1.0 + self.restitution[k]) * approach / gz
        return v + mu * z, mu

    def _rest_sign(self, k, q, g, approach):
        """The sign that makes the release function of resting bounce k positive when
        its row's multiplier pulls (the contact would have to pull s along d)."""
        s = self.solver
        self.rested[k] = True
        self.rel_sign[k] = 0.0
        if not self.used[self.row[k]]:
            return                              # held by other rows: never released
        d = self.direction[k] or (-1 if approach < 0.0 else 1)
        grow = self.quantities[list(self.quantities)[self.row[k]]].gradient_rate_bias(
            q, np.zeros(s.n_q))[0]
        z = constrained_solve(s.mass_matrix(q), s.constraint_jacobian(q), grow,
                              np.zeros(s.n_g), s.rank_tol, self._keeper(rows=False))
        self.rel_sign[k] = d * (1.0 if g @ z > 0.0 else -1.0)

    def _error(self, q) -> float:
        """max |g| and the active rows' errors."""
        err = float(np.max(np.abs(self.solver.constraints(q)), initial=0.0))
        if self.active.any():
            err = max(err, float(np.max(np.abs(self.values(q)[self.active]
                                               - self.held[self.active]))))
        return err

    def leaving(self, k: int, q, v, t: float, before: float) -> float:
        """The value watched value k counts as just after its event (docs/events.md):
        a bounce leaving its surface is on the side before the crossing, so that a
        return within the step is a new crossing; after a release, the bounce is.
        before: its value before the crossing."""
        if k >= self.ne:
            j = k - self.ne
            if self.direction[j] != 0:
                self.s0[j] = LEAVE if self.direction[j] < 0 else -LEAVE
            return -1.0
        s, grads = self.functions(q, v, t)
        if ACTIONS[self.action[k]] == "bounce" and self.direction[k] != 0:
            if float(grads[k] @ v) * self.direction[k] < 0.0:
                return LEAVE if self.direction[k] < 0 else -LEAVE
        if self.crosses(k, before, float(s[k])) or ACTIONS[self.action[k]] == "bounce":
            return float(s[k])
        # the projection of the located state moved it back over the crossing by its
        # tolerance: it stays past (the event happened)
        return LEAVE if (self.direction[k] or -np.sign(before) or 1) > 0 else -LEAVE

    def table(self) -> np.ndarray:
        return np.array(self.log, float).reshape(len(self.log), 11)


def _attributes(tree):
    import ast
    return [n for n in ast.walk(tree) if isinstance(n, ast.Attribute)]


def _rank(rows: np.ndarray) -> tuple[int, np.ndarray]:
    """The rank of rows by the SVD gap test (sigma > DECIDE_TOL sigma_1), and sigma."""
    if not rows.size:
        return 0, np.zeros(0)
    sv = np.linalg.svd(rows, compute_uv=False)
    if not sv[0] > 0.0:
        return 0, sv
    return int(np.sum(sv > rank_rule.DECIDE_TOL * sv[0])), sv
