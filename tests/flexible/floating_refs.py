"""Independent references for tests/flexible/test_floating.py, written without viz3d's
floating-frame code (viz3d.flexible.floating*).

* ``PolyBasis``: explicit polynomial shapes (sympy expressions in x) as a ``ShapeBasis``, so that a
  ``BarModel`` can carry them.
* ``SympyBar``: a uniform bar with a rectangular section, deformation fields given as polynomials
  and point masses. Every material point (x, y, z) of the bar's volume is placed by the linear
  field the FFR module documents, ``s = (x - x_G, y, z) + sum_k d_k u_k(x) eta_k + theta(x) x c``,
  ``c = (0, y, z)``, ``theta = sum b_k psi_k(x) eta_k`` over the fields with rotary inertia; sympy
  integrates ``rho V^T V`` exactly over the box (``V = d(body velocity)/d(v_B, omega, eta_dot)``),
  giving the kinetic energy ``T = 1/2 u^T M_B(eta) u`` in ``u = [v_B, omega, eta_dot]``
  (``v_B = R^T W_v``), and the first moment ``s_c(eta)``.
* ``hamel_velocity_forces``: the velocity terms of Lagrange's equations in quasi-velocities for a
  body with velocities ``[W_v, B_omega]`` (Hamel; Kirchhoff's form of Euler's equations with the
  momentum of a moving reference point): with ``p = dT/dv_B``, ``h = dT/domega``,

      d/dt (R p) = W_F,    h_dot + omega x h + v_B x p = B_tau,    d/dt dT/deta_dot - dT/deta = Q_eta,

  ``v_B_dot = R^T W_v_dot - omega x v_B``; everything except the terms in ``v_dot`` is minus the
  velocity force.
"""

from __future__ import annotations

import functools

import numpy as np
import sympy as sp

X = sp.Symbol("x")


class PolyBasis:
    """Polynomial shapes ``u_i(x)`` (and ``psi_i(x)``; default ``u_i'``) as a ``ShapeBasis``."""

    def __init__(self, length: float, u: list, psi: list | None = None):
        self.length = float(length)
        self.n_basis = len(u)
        self._u = [_coefficients(e) for e in u]
        self._psi = [_coefficients(e) for e in (psi if psi is not None else [sp.diff(e, X) for e in u])]

    def evaluate(self, x, field: str, order: int):
        coefs = {"u": self._u, "psi": self._psi}[field]
        x = np.asarray(x, dtype=float)
        return np.stack([np.polynomial.polynomial.polyval(x, np.polynomial.polynomial.polyder(c, order)) if order else
                         np.polynomial.polynomial.polyval(x, c) for c in coefs], axis=1)

    def breakpoints(self):
        return np.array([0.0, self.length])


def _coefficients(expr) -> np.ndarray:
    """Ascending float coefficients of a polynomial in x."""
    return np.array([float(c) for c in reversed(sp.Poly(expr, X).all_coeffs())])


def skew(a):
    return sp.Matrix([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])


class SympyBar:
    """Exact kinetic energy and first moment of a uniform bar with a rectangular section.

    Parameters
    ----------
    length, rho, width, depth : sympy Rationals
        L [m], density [kg/m^3], section sides [m]: ``depth`` along y, ``width`` along z.
    fields : list of (d, u_list, psi_list or None)
        d a 3-tuple of integers (unit vector), u_list polynomials in ``X``; psi_list the section
        rotations about ``b = e_x x d`` carrying rotary inertia, or None (none: rod or
        Euler-Bernoulli).
    point_masses : list of (x_j, m_j)
        On the axis, translation only.
    """

    def __init__(self, length, rho, width, depth, fields, point_masses):
        self.L, self.rho, self.width, self.depth = length, rho, width, depth
        self.fields, self.point_masses = fields, point_masses
        self.n = sum(len(u) for _, u, _ in fields)
        self.eta = sp.symbols(f"eta0:{self.n}")
        area = width * depth
        self.mass = rho * area * length + sum(m for _, m in point_masses)
        self.x_G = (rho * area * length**2 / 2 + sum(m * xj for xj, m in point_masses)) / self.mass

    def position(self, y, z):
        """s(x, y, z; eta) (3,) in B."""
        e_x = sp.Matrix([1, 0, 0])
        c = sp.Matrix([0, y, z])
        s = sp.Matrix([X - self.x_G, 0, 0]) + c
        k = 0
        for d, u_list, psi_list in self.fields:
            d = sp.Matrix(d)
            for i, u in enumerate(u_list):
                s += d * u * self.eta[k]
                if psi_list is not None:
                    s += (e_x.cross(d) * psi_list[i] * self.eta[k]).cross(c)
                k += 1
        return s

    def velocity_matrix(self, s):
        """V (3, 6 + n): body-axes velocity of the point per unit [v_B, omega, eta_dot]."""
        return sp.Matrix.hstack(sp.eye(3), -skew(s), s.jacobian(sp.Matrix(self.eta)))

    def _integral(self, f, y, z):
        """rho int f dV over the box plus sum m_j f(x_j, 0, 0), f a sympy expression in x, y, z."""
        g = sp.integrate(sp.expand(f), (y, -self.depth / 2, self.depth / 2), (z, -self.width / 2, self.width / 2))
        volume = self.rho * sp.integrate(sp.expand(g), (X, 0, self.L))
        return volume + sum((m * f.subs({X: xj, y: 0, z: 0}) for xj, m in self.point_masses), sp.S(0))

    @functools.cached_property
    def mass_matrix_body(self):
        """M_B(eta) (6 + n, 6 + n) as a sympy Matrix: int V^T V dm."""
        y, z = sp.symbols("y z")
        V = self.velocity_matrix(self.position(y, z))
        E = V.T * V
        size = 6 + self.n
        M = sp.zeros(size, size)
        for i in range(size):
            for j in range(i, size):
                M[i, j] = M[j, i] = self._integral(E[i, j], y, z)
        return M

    @functools.cached_property
    def first_moment(self):
        """s_c(eta) = int s dm (3,) as a sympy Matrix."""
        y, z = sp.symbols("y z")
        s = self.position(y, z)
        return sp.Matrix([self._integral(s[i], y, z) for i in range(3)])

    @functools.cached_property
    def numeric(self):
        """Lambdified M_B(eta) and [dM_B/deta_k]."""
        M = self.mass_matrix_body
        return sp.lambdify([self.eta], M, "numpy"), sp.lambdify([self.eta], [M.diff(e) for e in self.eta], "numpy")

    def numeric_first_moment(self, eta):
        """s_c(eta) (3,) evaluated."""
        return np.array(self.first_moment.subs(dict(zip(self.eta, eta))), dtype=float).ravel()

    def gravity_forces(self, R: np.ndarray, g: np.ndarray, eta: np.ndarray) -> np.ndarray:
        """Q_g (6 + n,) = -dV/d[W_r, dtheta, eta] of V = -g . (m W_r + R (I + skew(dtheta)) s_c(eta)) at
        W_r = 0, dtheta = 0 (dtheta: a small turn of B about its own axes, the virtual rotation of B_omega)."""
        W_r, dth = sp.symbols("r0:3"), sp.symbols("dth0:3")
        Rs, gs = sp.Matrix(R.tolist()), sp.Matrix(list(g))
        V = -(gs.T * (self.mass * sp.Matrix(W_r) + Rs * (sp.eye(3) + skew(dth)) * self.first_moment))[0, 0]
        q = list(W_r) + list(dth) + list(self.eta)
        at = {**{a: 0 for a in W_r + dth}, **dict(zip(self.eta, eta))}
        return np.array([float(-V.diff(a).subs(at)) for a in q])

def world_mass_matrix(M_B: np.ndarray, R: np.ndarray) -> np.ndarray:
    """M in [W_v, omega, eta_dot] from M_B in [v_B, omega, eta_dot], v_B = R^T W_v."""
    T = np.eye(M_B.shape[0])
    T[:3, :3] = R.T
    return T.T @ M_B @ T


def hamel_velocity_forces(M_B: np.ndarray, dM_B: list, R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Q_velocity (6 + n,) in world/body/modal rows from T = 1/2 u^T M_B(eta) u (module docstring)."""
    v_B, w, eta_dot = R.T @ v[:3], v[3:6], v[6:]
    u = np.concatenate([v_B, w, eta_dot])
    H = M_B @ u
    p, h = H[:3], H[3:6]
    u_dot_free = np.concatenate([-np.cross(w, v_B), np.zeros(3 + len(eta_dot))])
    H_dot = sum(np.asarray(dM, dtype=float) * ed for dM, ed in zip(dM_B, eta_dot)) @ u + M_B @ u_dot_free
    dT_deta = np.array([0.5 * u @ np.asarray(dM, dtype=float) @ u for dM in dM_B])
    E_t = R @ (H_dot[:3] + np.cross(w, p))
    E_r = H_dot[3:6] + np.cross(w, h) + np.cross(v_B, p)
    E_e = H_dot[6:] - dT_deta
    return -np.concatenate([E_t, E_r, E_e])


def frame_mass_matrix(model, reference: str) -> np.ndarray:
    """Mass matrix of the small-rotation linear frame (the former impact engine's, thesis ch. 6 and 10)
    in ``z = [frame coordinates, q]``: ``free`` = [X, q] (axial) or [Y, Theta, q] (bending, Y and Theta
    about x = 0), ``pinned`` = [Theta, q]. Couplings ``S1 = int rho A Phi``, ``S2 = int rho A x Phi``
    (+ ``S_psi`` for Timoshenko); the section's rotary inertia counts only for Timoshenko bars."""
    m = model
    rot_inertia = m.inertia_origin + (m.material.rho * m.section.second_moment * m.length
                                      if m.theory == "timoshenko" else 0.0)
    if m.kind == "axial":
        blocks, coupling = np.array([[m.mass]]), m.S1[None]
    elif reference == "free":
        blocks = np.array([[m.mass, m.static_moment], [m.static_moment, rot_inertia]])
        coupling = np.vstack([m.S1, m.S2 + m.S_psi])
    else:  # pinned
        blocks, coupling = np.array([[rot_inertia]]), (m.S2 + m.S_psi)[None]
    return np.block([[blocks, coupling], [coupling.T, m.M]])
