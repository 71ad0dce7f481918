"""Symbolic kinematics of the typical body (docs/elements.md): body frame, body-frame
angular velocity ``w_b = Phi_b q'`` and its bias ``c_w``, and body points
(position, velocity, partial-velocity matrix ``Dhat`` and bias acceleration).

Everything is built directly as sums and products of small vectors of symbols, so the
expressions stay plain trees for CSE; ``l, alpha, beta`` are parameters. Linear maps
from local speeds are kept per triple (:data:`Lin`) and placed into local columns only
at the end (:meth:`ClassSymbols.local`), so fixed triples never produce columns.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import sympy

from .symbols import ClassSymbols, Lin, Triple

E3 = sympy.eye(3)


def dot(a: sympy.Matrix, b: sympy.Matrix) -> sympy.Expr:
    """a . b of two 3 x 1 matrices, zero terms left out."""
    return sympy.Add(*[x * y for x, y in zip(a, b) if x != 0 and y != 0])


def cross(a: sympy.Matrix, b: sympy.Matrix) -> sympy.Matrix:
    """a x b of two 3 x 1 matrices."""
    return sympy.Matrix([a[1] * b[2] - a[2] * b[1],
                         a[2] * b[0] - a[0] * b[2],
                         a[0] * b[1] - a[1] * b[0]])


def skew(a: sympy.Matrix) -> sympy.Matrix:
    """~a, the cross-product matrix: skew(a) * b == a x b."""
    return sympy.Matrix([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])


def lin_combine(*terms: tuple[sympy.Expr | sympy.Matrix, Lin]) -> Lin:
    """sum_k c_k L_k for scalar or matrix coefficients c_k (a matrix multiplies each
    block from the left)."""
    out: Lin = {}
    for coef, lin in terms:
        for name, block in lin.items():
            part = coef * block
            out[name] = out[name] + part if name in out else part
    return out


def lin_row(x: sympy.Matrix, lin: Lin) -> Lin:
    """x^T L as per-triple 1 x 3 blocks; transposed, the generalized force L^T x."""
    return {name: x.T * block for name, block in lin.items()}


@dataclass(frozen=True)
class PointKin:
    """A point of an element: position r, velocity r' (linear in q'), Dhat = dr'/dq'
    per triple, and the bias acceleration (r'' at q'' = 0)."""
    pos: sympy.Matrix
    vel: sympy.Matrix
    dhat: Lin
    bias: sympy.Matrix


def plain_point(t: Triple) -> PointKin:
    """A named point: r is its triple, Dhat = E, no bias."""
    return PointKin(t.pos, t.vel, {t.name: E3} if t.moving else {}, sympy.zeros(3, 1))


class BodyFrame:
    """Frame of a body with points ri, rj and unit vector u (docs/elements.md)."""

    def __init__(self, ri: Triple, rj: Triple, u: Triple,
                 l: sympy.Expr, alpha: sympy.Expr, beta: sympy.Expr):
        self.ri, self.rj, self.u = ri, rj, u
        self.l, self.alpha, self.beta = l, alpha, beta

    @cached_property
    def rij(self) -> sympy.Matrix:
        return self.rj.pos - self.ri.pos

    @cached_property
    def rij_dot(self) -> sympy.Matrix:
        return self.rj.vel - self.ri.vel

    @cached_property
    def e1(self) -> sympy.Matrix:
        return self.rij / self.l

    @cached_property
    def e2(self) -> sympy.Matrix:
        return (self.u.pos - self.beta * self.e1) / self.alpha

    @cached_property
    def e3(self) -> sympy.Matrix:
        return cross(self.rij, self.u.pos) / (self.alpha * self.l)

    @cached_property
    def R(self) -> sympy.Matrix:
        """[e1 e2 e3]: body frame to global (a rotation on the constraint manifold)."""
        return sympy.Matrix.hstack(self.e1, self.e2, self.e3)

    def rij_blocks(self, block: sympy.Matrix) -> Lin:
        """Blocks of a map that acts on r_ij' only: -block on ri, +block on rj."""
        out: Lin = {}
        if self.ri.moving:
            out[self.ri.name] = -block
        if self.rj.moving:
            out[self.rj.name] = block
        return out

    @cached_property
    def phi_b(self) -> Lin:
        """Phi_b with w_b = Phi_b q'. From w_b = [e2'.e3, e3'.e1, e1'.e2] with
        (r_ij x u').r_ij = 0 and e1 x u = alpha e3:
        w_b = [(u' - beta r_ij'/l).e3/alpha, -r_ij'.e3/l, r_ij'.e2/l]."""
        l, alpha, beta, e2, e3 = self.l, self.alpha, self.beta, self.e2, self.e3
        on_rij = sympy.Matrix.vstack(-beta / (alpha * l) * e3.T, -e3.T / l, e2.T / l)
        out = self.rij_blocks(on_rij)
        if self.u.moving:
            out[self.u.name] = sympy.Matrix.vstack(e3.T / alpha, sympy.zeros(2, 3))
        return out

    @cached_property
    def w_b(self) -> sympy.Matrix:
        """Body-frame angular velocity, the same terms as ``phi_b`` applied to q'."""
        l, alpha, beta, e2, e3 = self.l, self.alpha, self.beta, self.e2, self.e3
        rd, ud = self.rij_dot, self.u.vel
        return sympy.Matrix([(dot(ud, e3) - beta / l * dot(rd, e3)) / alpha,
                             -dot(rd, e3) / l,
                             dot(rd, e2) / l])

    @cached_property
    def c_w(self) -> sympy.Matrix:
        """Angular acceleration bias: w_b' = Phi_b q'' + c_w.

        Differentiating the rows of ``w_b``: e1, e2 are linear in q, so rows 1 and 3
        give e2'.e3' and e1'.e2'. Row 2 is -r_ij'.e3/l, whose derivative leaves
        -e1'.e3' (not +e3'.e1': e3 is quadratic in q, e3'' holds 2 r_ij' x u'/(alpha l)).
        Identically zero triple products (a . (a x b) = 0) are left out."""
        l, alpha, beta = self.l, self.alpha, self.beta
        rij, rd, u, ud = self.rij, self.rij_dot, self.u.pos, self.u.vel
        rd_x_u = cross(rd, u)
        rij_x_ud = cross(rij, ud)
        return sympy.Matrix([
            (dot(ud, rd_x_u) - beta / l * dot(rd, rij_x_ud)) / (alpha ** 2 * l),
            -dot(rd, rij_x_ud) / (alpha * l ** 2),
            (dot(rd, ud) - beta / l * dot(rd, rd)) / (alpha * l)])

    @cached_property
    def w(self) -> sympy.Matrix:
        """Global angular velocity R w_b."""
        return self.e1 * self.w_b[0] + self.e2 * self.w_b[1] + self.e3 * self.w_b[2]

    def point(self, b1: sympy.Expr, b2: sympy.Expr, b3: sympy.Expr) -> PointKin:
        """The body point r = ri + b1 r_ij + b2 u + c (r_ij x u), c = b3/(alpha l)."""
        ri, u, rij, rd = self.ri, self.u, self.rij, self.rij_dot
        c = b3 / (self.alpha * self.l)
        pos = ri.pos + b1 * rij + b2 * u.pos + c * cross(rij, u.pos)
        vel = ri.vel + b1 * rd + b2 * u.vel + c * (cross(rd, u.pos) + cross(rij, u.vel))
        cu = c * skew(u.pos)
        dhat = self.rij_blocks(b1 * E3 - cu)
        if ri.moving:                     # ri enters as ri and through r_ij = rj - ri
            dhat[ri.name] = E3 + dhat[ri.name]
        if u.moving:
            dhat[u.name] = b2 * E3 + c * skew(rij)
        return PointKin(pos, vel, dhat, 2 * c * cross(rd, u.vel))


def body_frame(s: ClassSymbols, prefix: str = "") -> BodyFrame:
    """The body frame of an element's triples ``<prefix>ri/rj/u`` and scalars
    ``<prefix>l/alpha/beta`` (prefix "" for body, force, torque; "A." for an end)."""
    return BodyFrame(s.triple(prefix + "ri"), s.triple(prefix + "rj"), s.triple(prefix + "u"),
                     s.scalar(prefix + "l"), s.scalar(prefix + "alpha"),
                     s.scalar(prefix + "beta"))


def end_point(s: ClassSymbols, end: str, end_kind: str) -> PointKin:
    """The point of an end: a named point (triple ``<end>.r``) or a body point."""
    if end_kind == "point":
        return plain_point(s.triple(f"{end}.r"))
    frame = body_frame(s, f"{end}.")
    return frame.point(*(s.scalar(f"{end}.{b}") for b in ("b1", "b2", "b3")))
