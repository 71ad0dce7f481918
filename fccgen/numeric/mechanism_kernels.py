"""NumPy kernels of the mechanism level's time-dependent rows and loads and of the
linear spring-damper (docs/elements.md, docs/joints.md "Drivers"), registered in
:data:`fccgen.numeric.elements.KIND_KERNELS` when the package is imported.

f(t) and its derivatives come from :mod:`.time_jets` (forward-mode differentiation of
the expression, no SymPy); the derivatives of the rows in q and the chain rule in t
are written out here by hand, independently of the symbolic path.
"""
from __future__ import annotations

from functools import cached_property

import numpy as np

from .elements import KIND_KERNELS, ElementKernels, ForceKernels, TorqueKernels
from .kinematics import EYE, cross
from .time_jets import time_function
# -- drivers (docs/joints.md, "Drivers") ----------------------------------------------

class DriverKernels(ElementKernels):
    """A rheonomic row g(q, t); subclasses give ``_driven()``: (value, partials per
    triple, q-bias q'^T (d2g/dq2) q', dg/dt, 2 (d2g/dq dt) q' + d2g/dt2)."""

    @cached_property
    def f(self) -> tuple[float, float, float]:
        return time_function(self.cls.function)(self.x.s["t"])

    def _rows(self):
        g, blocks, bias_q, _, bias_t = self._driven
        return [(g, blocks, bias_q + bias_t)]

    @cached_property
    def _driven(self):
        raise NotImplementedError

    def constraint_rate(self) -> np.ndarray:
        return np.array([self._driven[3]])


class DriverAngleKernels(DriverKernels):
    """g = -s P + c T with s, c = sin f, cos f, P = b.a and T = u.(a x b)
    (= b.(u x a)): dg/dt = f' (-c P - s T); with P'', T'' at q'' = 0
    (2 b'.a', 2 [u'.(a' x b) + u'.(a x b') + u.(a' x b')]), the bias is
    -s'' P - 2 s' P' - s P'' + c'' T + 2 c' T' + c T''."""

    @cached_property
    def _driven(self):
        x = self.x
        u, a, b = (x.pos[n] for n in ("u", "a", "b"))
        du, da, db = (x.vel[n] for n in ("u", "a", "b"))
        f, fd, fdd = self.f
        s, c = np.sin(f), np.cos(f)
        sd, cd = c * fd, -s * fd
        sdd, cdd = -s * fd * fd + c * fdd, -c * fd * fd - s * fdd
        P, T = b @ a, u @ cross(a, b)
        Pd = db @ a + b @ da
        Td = du @ cross(a, b) + u @ cross(da, b) + u @ cross(a, db)
        Pdd = 2.0 * db @ da
        Tdd = 2.0 * (du @ cross(da, b) + du @ cross(a, db) + u @ cross(da, db))
        blocks = {"u": c * cross(a, b), "a": -s * b + c * cross(b, u),
                  "b": -s * a + c * cross(u, a)}
        bias_q = -s * Pdd + c * Tdd
        bias_t = -sdd * P - 2.0 * sd * Pd + cdd * T + 2.0 * cd * Td
        return -s * P + c * T, blocks, bias_q, -sd * P + cd * T, bias_t


class DriverPositionKernels(DriverKernels):
    """g = u.(r_b - r_a) - f: dg/dt = -f', bias 2 u'.(r_b' - r_a') - f''."""

    @cached_property
    def _driven(self):
        x = self.x
        u, d = x.pos["u"], x.pos["rb"] - x.pos["ra"]
        dd = x.vel["rb"] - x.vel["ra"]
        f, fd, fdd = self.f
        return (u @ d - f, {"u": d, "rb": u, "ra": -u}, 2.0 * x.vel["u"] @ dd, -fd, -fdd)


class DriverDistanceKernels(DriverKernels):
    """g = d.d - f^2 (d = r_b - r_a): dg/dt = -2 f f', bias 2 d'.d' - 2 (f'^2 + f f'')."""

    @cached_property
    def _driven(self):
        x = self.x
        d, dd = x.pos["rb"] - x.pos["ra"], x.vel["rb"] - x.vel["ra"]
        f, fd, fdd = self.f
        return (d @ d - f * f, {"rb": 2.0 * d, "ra": -2.0 * d}, 2.0 * dd @ dd,
                -2.0 * f * fd, -2.0 * (fd * fd + f * fdd))


class DriverCoordinateKernels(DriverKernels):
    """g = e.r - c0 - f: B = e on r, dg/dt = -f', bias -f''."""

    @cached_property
    def _driven(self):
        x, s = self.x, self.x.s
        e = np.array([s["ex"], s["ey"], s["ez"]])
        f, fd, fdd = self.f
        return e @ x.pos["r"] - s["c0"] - f, {"r": e}, 0.0, -fd, -fdd


KIND_KERNELS.update({"driver_coordinate": DriverCoordinateKernels})
KIND_KERNELS.update({"driver_angle": DriverAngleKernels,
                     "driver_position": DriverPositionKernels,
                     "driver_distance": DriverDistanceKernels})



def input_values(cls, scalars) -> dict:
    """name -> value of the inputs the class reads (its parameters "input:NAME")."""
    from ..plan.classes import input_parameter
    return {n: scalars[input_parameter(n)] for n in cls.inputs}


class _TimedLoad:
    """A load of time (kinds force_t, torque_t): the constant-load kernels with the
    components (names) set to the class's three functions at the parameter t."""
    names: tuple[str, str, str]

    def __init__(self, cls, q, v, p):
        super().__init__(cls, q, v, p)
        t = self.x.s["t"]
        inputs = input_values(cls, self.x.s)
        for name, text in zip(self.names, cls.function.split(";")):
            self.x.s[name] = time_function(text)(t, inputs)[0]


class ForceTKernels(_TimedLoad, ForceKernels):
    """f = Dhat^T F(t); a force of time has no potential."""
    names = ("Fx", "Fy", "Fz")


class TorqueTKernels(_TimedLoad, TorqueKernels):
    """f = Phi_b^T (R^T T(t))."""
    names = ("Tx", "Ty", "Tz")


KIND_KERNELS.update({"force_t": ForceTKernels, "torque_t": TorqueTKernels})


class LinearSpringKernels(ElementKernels):
    """s = u.d (d = r_b - r_a), s' = u'.d + u.d'; T = k (s - L) + c s';
    f = -T g with g = ds/dq = [d on u, u on r_b, -u on r_a]; energy k (s - L)^2 / 2.
    df/dq = -g (k g + c ds'/dq)^T - T d2s/dq2, ds'/dq = [d' on u, u' on r_b, -u' on
    r_a], d2s/dq2 = E between u and r_b, -E between u and r_a; df/dq' = -c g g^T."""

    @cached_property
    def parts(self):
        x, s = self.x, self.x.s
        u, du = x.pos["u"], x.vel["u"]
        d, dd = x.pos["rb"] - x.pos["ra"], x.vel["rb"] - x.vel["ra"]
        pos, speed = u @ d, du @ d + u @ dd
        g = x.columns({"u": d, "rb": u, "ra": -u}, 1)[0]
        g_speed = x.columns({"u": dd, "rb": du, "ra": -du}, 1)[0]
        return pos, s["k"] * (pos - s["L"]) + s["c"] * speed, g, g_speed

    def applied_forces(self):
        _, tension, g, _ = self.parts
        return -tension * g

    def energy(self):
        pos = self.parts[0]
        return [0.0, self.x.s["k"] * (pos - self.x.s["L"]) ** 2 / 2]

    def force_jacobian_q(self):
        _, tension, g, g_speed = self.parts
        x = self.x
        hess = np.zeros((x.cls.n_q, x.cls.n_q))
        cols = {n: x.columns({n: EYE}, 3) for n in ("u", "ra", "rb")}
        for a, b, sign in (("u", "rb", 1.0), ("u", "ra", -1.0)):
            block = sign * cols[a].T @ cols[b]
            hess += block + block.T
        return -np.outer(g, x.s["k"] * g + x.s["c"] * g_speed) - tension * hess

    def force_jacobian_v(self):
        g = self.parts[2]
        return -self.x.s["c"] * np.outer(g, g)


KIND_KERNELS["linear_spring"] = LinearSpringKernels
