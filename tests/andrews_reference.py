"""Andrews' squeezing mechanism in its published minimal coordinates, independent of
fccgen: the reference of examples/andrews.yaml.

Source: the seven-body planar mechanism of Giles (1978) and Manning (1981) as
presented by Schiehlen (Multibody Systems Handbook, 1990) and by Hairer & Wanner,
"Solving Ordinary Differential Equations II", 2nd ed., Springer 1996, section VII.7;
the equations, parameters, consistent initial values and the reference solution at
t = 0.03 s are those of problem ``andrews`` of the Test Set for IVP Solvers
(F. Mazzia, F. Iavernaro et al., University of Bari, www.dm.uniba.it/~testset;
file andrews.f, revision 1.2 of 2006-10-02; the same values are in the R package
deTestSet, ``andrews``). The test set's reference at t = 0.03 was computed with
PSIDE at rtol = atol = 1e-14 (Cray C90): the 7 angles, 7 rates, 7 accelerations
and 6 multipliers to 16 digits. They are copied below (:data:`Q_END`,
:data:`QD_END`); its consistent initial values are :data:`Q0` (at rest),
:data:`QDD0` and :data:`LAMBDA0`.

The coordinates are seven angles, q = (beta, Theta, gamma, Phi, delta, Omega,
epsilon), SI units, no gravity. The equations are M(q) q'' = f(q, q') - G(q)^T lambda,
g(q) = 0 with the M, f, G, g of the test set (written out in :func:`mass_matrix`,
:func:`forces` and :data:`LOOPS`). What each angle is, read from g and M:

- body 1, the crank, turns about the fixed point O = (0, 0) at the absolute angle
  beta; F = O + rr (cos beta, sin beta); mass centre at ra from O on OF; the drive
  torque mom acts on it;
- body 2, the rod F-E of length d, at the absolute angle beta + Theta + pi:
  E = F - d (cos(beta + Theta), sin(beta + Theta)); mass centre at da from F on FE;
- body 3 turns about the fixed point B at the angle gamma: E = B + ss (sin gamma,
  -cos gamma), the spring's end D = B + sc (sin gamma, -cos gamma) + sd (cos gamma,
  sin gamma); mass centre at sqrt(sa^2 + sb^2) from B;
- body 5 turns about the fixed point A at the angle delta: G = A + zt (cos delta,
  sin delta); mass centre at sqrt(ta^2 + tb^2) from A;
- body 4, the rod G-E of length e, at the absolute angle Phi + delta: E = G + e
  (sin(Phi + delta), -cos(Phi + delta)); mass centre at ea from E;
- body 7 turns about A at the angle epsilon: H = A + u (sin epsilon, -cos epsilon);
  mass centre at sqrt(ua^2 + ub^2) from A;
- body 6, the rod H-E of length zf, at the absolute angle Omega + epsilon:
  E = H + zf (cos(Omega + epsilon), sin(Omega + epsilon)); mass centre at fa from E;
- the spring (stiffness c0, free length l0) pulls D towards the fixed point C.

The three loops close at E: g = 0 says that E reached along bodies 1-2 is the E of
body 3 (rows 1, 2), of bodies 5-4 (rows 3, 4) and of bodies 7-6 (rows 5, 6).
Bodies 1, 3, 5 and 7 turn about fixed points and nothing acts on their mass centres,
so the equations fix only the distance of those mass centres from their pivots;
bodies 2, 4 and 6 have their mass centres on their axis (the cross terms of M say so).

:func:`solve` integrates the index-1 form (the constraints' second derivatives with
the multipliers, solved at every evaluation) with SciPy's DOP853; :func:`points`
gives the positions of the named points of the mechanism from the angles.
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

P = dict(m1=.04325, m2=.00365, m3=.02373, m4=.00706, m5=.07050, m6=.00706, m7=.05498,
         xa=-.06934, ya=-.00227, xb=-.03635, yb=.03273, xc=.014, yc=.072, c0=4530.0,
         i1=2.194e-6, i2=4.410e-7, i3=5.255e-6, i4=5.667e-7, i5=1.169e-5, i6=5.667e-7,
         i7=1.912e-5, d=28e-3, da=115e-4, e=2e-2, ea=1421e-5, rr=7e-3, ra=92e-5,
         l0=7785e-5, ss=35e-3, sa=1874e-5, sb=1043e-5, sc=18e-3, sd=2e-2, ta=2308e-5,
         tb=916e-5, u=4e-2, ua=1228e-5, ub=449e-5, zf=2e-2, zt=4e-2, fa=1421e-5,
         mom=33e-3)
T_END = 0.03
NAMES = ("beta", "Theta", "gamma", "Phi", "delta", "Omega", "epsilon")
# the test set's consistent initial values (at rest)
Q0 = np.array([-0.0617138900142764496358948458001, 0.0,
               0.455279819163070380255912382449, 0.222668390165885884674473185609,
               0.487364979543842550225598953530, -0.222668390165885884674473185609,
               1.23054744454982119249735015568])
QDD0 = np.array([14222.4439199541138705911625887, -10666.8329399655854029433719415,
                 0.0, 0.0, 0.0, 0.0, 0.0])
LAMBDA0 = np.array([98.5668703962410896057654982170, -6.12268834425566265503114393122,
                    0.0, 0.0, 0.0, 0.0])
# the test set's reference solution at t = 0.03 (PSIDE, rtol = atol = 1e-14)
Q_END = np.array([0.1581077119629904e+2, -0.1575637105984298e+2, 0.4082224013073101e-1,
                  -0.5347301163226948e+0, 0.5244099658805304e+0, 0.5347301163226948e+0,
                  0.1048080741042263e+1])
QD_END = np.array([0.1139920302151208e+4, -0.1424379294994111e+4, 0.1103291221937134e+2,
                   0.1929337464421385e+2, 0.5735699284790808e+0, -0.1929337464421385e+2,
                   0.3231791658026955e+0])

# The constraints g(q) as sums of terms  c * cos(k . q)  or  c * sin(k . q)  plus a
# constant: (constant, [(c, "cos" | "sin", k), ...]) per row, k over the 7 angles.
_B, _T, _G, _F, _D, _O, _E = np.eye(7)
_p = P
LOOPS = [
    (-_p["xb"], [(_p["rr"], "cos", _B), (-_p["d"], "cos", _B + _T),
                 (-_p["ss"], "sin", _G)]),
    (-_p["yb"], [(_p["rr"], "sin", _B), (-_p["d"], "sin", _B + _T),
                 (_p["ss"], "cos", _G)]),
    (-_p["xa"], [(_p["rr"], "cos", _B), (-_p["d"], "cos", _B + _T),
                 (-_p["e"], "sin", _F + _D), (-_p["zt"], "cos", _D)]),
    (-_p["ya"], [(_p["rr"], "sin", _B), (-_p["d"], "sin", _B + _T),
                 (_p["e"], "cos", _F + _D), (-_p["zt"], "sin", _D)]),
    (-_p["xa"], [(_p["rr"], "cos", _B), (-_p["d"], "cos", _B + _T),
                 (-_p["zf"], "cos", _O + _E), (-_p["u"], "sin", _E)]),
    (-_p["ya"], [(_p["rr"], "sin", _B), (-_p["d"], "sin", _B + _T),
                 (-_p["zf"], "sin", _O + _E), (_p["u"], "cos", _E)]),
]


def constraints(q, qd):
    """(g, G, gamma): the constraint values, their Jacobian and the part of their
    second time derivative without q'' (g'' = G q'' + gamma)."""
    g, G, gam = np.zeros(6), np.zeros((6, 7)), np.zeros(6)
    for row, (const, terms) in enumerate(LOOPS):
        g[row] = const
        for c, fn, k in terms:
            phi, rate = k @ q, k @ qd
            if fn == "cos":       # c cos(phi): c' = -c sin(phi) phi'
                g[row] += c * np.cos(phi)
                G[row] -= c * np.sin(phi) * k
                gam[row] -= c * np.cos(phi) * rate ** 2
            else:                 # c sin(phi): c' = c cos(phi) phi'
                g[row] += c * np.sin(phi)
                G[row] += c * np.cos(phi) * k
                gam[row] -= c * np.sin(phi) * rate ** 2
    return g, G, gam


def mass_matrix(q):
    p = P
    _, th, _, ph, _, om, _ = q
    e_ea, zf_fa = p["e"] - p["ea"], p["zf"] - p["fa"]
    M = np.zeros((7, 7))
    M[0, 0] = (p["m1"] * p["ra"] ** 2 + p["m2"] * (p["rr"] ** 2 - 2 * p["da"] * p["rr"]
               * np.cos(th) + p["da"] ** 2) + p["i1"] + p["i2"])
    M[1, 0] = p["m2"] * (p["da"] ** 2 - p["da"] * p["rr"] * np.cos(th)) + p["i2"]
    M[1, 1] = p["m2"] * p["da"] ** 2 + p["i2"]
    M[2, 2] = p["m3"] * (p["sa"] ** 2 + p["sb"] ** 2) + p["i3"]
    M[3, 3] = p["m4"] * e_ea ** 2 + p["i4"]
    M[4, 3] = p["m4"] * (e_ea ** 2 + p["zt"] * e_ea * np.sin(ph)) + p["i4"]
    M[4, 4] = (p["m4"] * (p["zt"] ** 2 + 2 * p["zt"] * e_ea * np.sin(ph) + e_ea ** 2)
               + p["m5"] * (p["ta"] ** 2 + p["tb"] ** 2) + p["i4"] + p["i5"])
    M[5, 5] = p["m6"] * zf_fa ** 2 + p["i6"]
    M[6, 5] = p["m6"] * (zf_fa ** 2 - p["u"] * zf_fa * np.sin(om)) + p["i6"]
    M[6, 6] = (p["m6"] * (zf_fa ** 2 - 2 * p["u"] * zf_fa * np.sin(om) + p["u"] ** 2)
               + p["m7"] * (p["ua"] ** 2 + p["ub"] ** 2) + p["i6"] + p["i7"])
    return np.tril(M) + np.tril(M, -1).T


def forces(q, qd):
    """f(q, q'): the drive torque, the spring, and the velocity terms of M."""
    p = P
    _, th, ga, ph, _, om, _ = q
    bp, tp, _, pp, dp, op, ep = qd
    xd = p["sd"] * np.cos(ga) + p["sc"] * np.sin(ga) + p["xb"]
    yd = p["sd"] * np.sin(ga) - p["sc"] * np.cos(ga) + p["yb"]
    length = np.hypot(xd - p["xc"], yd - p["yc"])
    force = -p["c0"] * (length - p["l0"]) / length
    fx, fy = force * (xd - p["xc"]), force * (yd - p["yc"])
    k2 = p["m2"] * p["da"] * p["rr"]
    k4 = p["m4"] * p["zt"] * (p["e"] - p["ea"])
    k6 = p["m6"] * p["u"] * (p["zf"] - p["fa"])
    return np.array([
        p["mom"] - k2 * tp * (tp + 2 * bp) * np.sin(th),
        k2 * bp ** 2 * np.sin(th),
        fx * (p["sc"] * np.cos(ga) - p["sd"] * np.sin(ga))
        + fy * (p["sd"] * np.cos(ga) + p["sc"] * np.sin(ga)),
        k4 * dp ** 2 * np.cos(ph),
        -k4 * pp * (pp + 2 * dp) * np.cos(ph),
        -k6 * ep ** 2 * np.cos(om),
        k6 * op * (op + 2 * ep) * np.cos(om)])


def accelerations(q, qd):
    """(q'', lambda) of M q'' + G^T lambda = f, G q'' = -gamma."""
    _, G, gam = constraints(q, qd)
    K = np.zeros((13, 13))
    K[:7, :7], K[:7, 7:], K[7:, :7] = mass_matrix(q), G.T, G
    x = np.linalg.solve(K, np.concatenate([forces(q, qd), -gam]))
    return x[:7], x[7:]


def solve(t, rtol=1e-13, atol=1e-13):
    """The angles and rates at the times t (shape (len(t), 14)), from the test set's
    initial values, by DOP853 on the index-1 form."""
    t = np.asarray(t, float)
    sol = solve_ivp(lambda _t, y: np.concatenate([y[7:], accelerations(y[:7], y[7:])[0]]),
                    (0.0, t[-1]), np.concatenate([Q0, np.zeros(7)]), method="DOP853",
                    t_eval=t, rtol=rtol, atol=atol)
    if sol.status != 0:
        raise RuntimeError(f"integration failed: {sol.message}")
    return sol.y.T


def _turn(v, angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def body_angles(q):
    """Each body's absolute angle (of its first axis below), by body 1 .. 7."""
    b, th, ga, ph, de, om, ep = q
    return {"body1": b, "body2": b + th + np.pi, "body3": ga - np.pi / 2,
            "body4": ph + de - np.pi / 2, "body5": de, "body6": om + ep,
            "body7": ep - np.pi / 2}


def points(q) -> dict:
    """Named points (x, y) of the mechanism at the angles q: the fixed O, A, B, C, the
    joints F, E, G, H, the spring's end D and each body's mass centre (the mass
    centres of bodies 3, 5, 7 at the place examples/andrews.yaml gives them: at
    (sa, sb), (ta, tb), (ua, ub) in the axes of their body, see :func:`body_axes`)."""
    p = P
    a = body_angles(q)
    O, A, B = np.zeros(2), np.array([p["xa"], p["ya"]]), np.array([p["xb"], p["yb"]])
    x = {k: _turn([1.0, 0.0], v) for k, v in a.items()}        # each body's first axis
    y = {k: _turn([0.0, 1.0], v) for k, v in a.items()}
    F = O + p["rr"] * x["body1"]
    E = F + p["d"] * x["body2"]
    G = A + p["zt"] * x["body5"]
    H = A + p["u"] * x["body7"]
    return dict(
        O=O, A=A, B=B, C=np.array([p["xc"], p["yc"]]), F=F, E=E, G=G, H=H,
        D=B + p["sc"] * x["body3"] + p["sd"] * y["body3"],
        E3=B + p["ss"] * x["body3"], E4=G + p["e"] * x["body4"],
        E6=H + p["zf"] * x["body6"],
        body1=O + p["ra"] * x["body1"], body2=F + p["da"] * x["body2"],
        body3=B + p["sa"] * x["body3"] + p["sb"] * y["body3"],
        body4=E - p["ea"] * x["body4"],
        body5=A + p["ta"] * x["body5"] + p["tb"] * y["body5"],
        body6=E - p["fa"] * x["body6"],
        body7=A + p["ua"] * x["body7"] + p["ub"] * y["body7"])


def body_axes(q) -> dict:
    """Each body's axes (x, y) in the plane at the angles q: x along O-F (body 1),
    F-E (2), B-E (3), G-E (4), A-G (5), H-E (6), A-H (7); y = z x x."""
    return {k: (_turn([1.0, 0.0], v), _turn([0.0, 1.0], v))
            for k, v in body_angles(q).items()}
