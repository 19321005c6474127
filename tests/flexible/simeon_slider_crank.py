"""Simeon's flexible slider crank, transcribed from the Test Set for IVP Solvers (no viz3d code).

Source: problem "crank" of the Test Set for IVP Solvers (F. Mazzia, C. Magherini, University of
Bari; file crank.f, revision 1.2 of 2006, subroutine RESMBS written by B. Simeon in 1995/97), as
shipped in the R package deTestSet (src/Ex_crank.f, R/ex_crank.R), after

    B. Simeon, "Modelling a flexible slider crank mechanism by a mixed system of DAEs and PDEs",
    Math. Modelling of Systems 2 (1996) 1-18.

Planar model: rigid crank (angle phi1, length L1), connecting rod on a floating frame (angle phi2)
through the crank pin and, undeformed, the piston pin, slider x3 (mass M3). Elastic rod: lateral
v(x) = q1 sin(pi x / L2) + q2 sin(2 pi x / L2), axial u(x) = q3 N3(x) + q4 N4(x) (quadratic, nodes at
L2 / 2 and L2); every inertia coupling term of the floating frame; linear stiffness (the test set's
default, ipar = 0, 0); no gravity. phi1(t) is prescribed (crank.f: phi1 = OMEGA t; here any profile
with its two derivatives). The slider sits at the rod's end x = L2 + u(L2) = L2 + q4 on its axis.

Equations, index-1 form: M(p, q) w + G^T lam = f(p, q, p', q'), G w = -gamma, with G = dC/d(p, q)
and gamma the acceleration terms of the three constraints; integrated here with scipy's DOP853.

``axial=False`` drops q3 and q4 (the rod axially rigid: Simeon's KU = 0), which is the engine's
Euler-Bernoulli bar on a pinned-pinned frame with its two lowest modes.

The printed reference (subroutine cranksoln: MEBDFI at rtol = atol = 1e-14, t = 0.1 s, initial
values ``INI1`` of crank.f, 24 components) is ``REFERENCE_T01``; components 4..7 are q1..q4 [m],
11..14 their rates [m/s].
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

# crank.f's data (common block crankcom): [kg], [m], [kg m^2], [Pa], [-], [m], [kg/m^3], [rad/s]
M1, M2, M3 = 0.36, 0.151104, 0.075552
L1, L2 = 0.15, 0.30
J1, J2 = 0.002727, 0.0045339259
EE, NUE, BB, HH, RHO, OMEGA = 0.20e12, 0.30, 0.0080, 0.0080, 7870.0, 150.0
PI_CRANK = 3.1415927  # crank.f's PARAMETER (PI = 3.1415927D0), kept to reproduce its numbers

#: crank.f's consistent initial values (R/ex_crank.R, ini = 1): positions, velocities (7 + 7).
INI1 = np.array([0.0, 0.0, 0.450016933, 0.0, 0.0, 0.103339863e-4, 0.169327969e-4,
                 0.150000000e3, -0.749957670e2, -0.268938672e-5, 0.444896105, 0.463434311e-2,
                 -0.178591076e-5, -0.268938672e-5])

#: crank.f's subroutine cranksoln: y(t = 0.1) for INI1 (positions, velocities; 7 + 7 of 24).
REFERENCE_T01 = np.array([
    0.1500000000000104e+002, -0.3311734988256260e+000, 0.1697373328427860e+000,
    0.1893192899613509e-003, 0.2375751249879174e-004, -0.5323896770569702e-005,
    -0.8363313279112129e-005,
    0.1500000000000000e+003, 0.6025346755138369e+002, -0.8753116326670527e+001,
    -0.3005541400289738e-001, -0.5500431812571696e-002, 0.4974111734266989e-003,
    0.1105560003626645e-002])


def _matrices(axial: bool):
    """crank.f's FE matrices MQ, KQ, BQ and vectors c1, c2, c12, c21 (the first call of RESMBS)."""
    pi = PI_CRANK
    facm, fack, facb = RHO * BB * HH * L2, EE * BB * HH / L2, BB * HH * L2
    MQ, KQ, BQ = np.zeros((4, 4)), np.zeros((4, 4)), np.zeros((4, 4))
    c1, c2, c12, c21 = np.zeros(4), np.zeros(4), np.zeros(4), np.zeros(4)
    MQ[0, 0] = MQ[1, 1] = facm * 0.5
    MQ[2, 2], MQ[2, 3], MQ[3, 2], MQ[3, 3] = facm * 8.0, facm, facm, facm * 2.0
    KQ[0, 0] = fack * pi**4 / 24.0 * (HH / L2) ** 2
    KQ[1, 1] = fack * pi**4 * 2.0 / 3.0 * (HH / L2) ** 2
    KQ[2, 2], KQ[2, 3], KQ[3, 2], KQ[3, 3] = fack * 16 / 3, -fack * 8 / 3, -fack * 8 / 3, fack * 7 / 3
    BQ[0, 2], BQ[0, 3], BQ[1, 3] = -facb * 16 / pi**3, facb * (8 / pi**3 - 1 / pi), facb * 0.5 / pi
    BQ[2, 0], BQ[3, 0], BQ[3, 1] = -BQ[0, 2], -BQ[0, 3], -BQ[1, 3]
    c1[2], c1[3] = facb * 2 / 3, facb / 6
    c2[0] = facb * 2 / pi
    c12[2], c12[3] = L2 * facb / 3, L2 * facb / 6
    c21[0], c21[1] = L2 * facb / pi, -L2 * facb * 0.5 / pi
    keep = slice(0, 4) if axial else slice(0, 2)
    return (MQ[keep, keep], KQ[keep, keep], BQ[keep, keep], c1[keep], c2[keep], c12[keep], c21[keep])


class SimeonCrank:
    """Simeon's slider crank as an ODE in y = (phi2, x3, q, phi2', x3', q') with phi1(t) prescribed.

    Parameters
    ----------
    crank : callable
        ``t -> (phi1, phi1_dot, phi1_ddot)`` [rad, rad/s, rad/s^2].
    axial : bool
        Keep the axial nodes q3, q4 (crank.f) or drop them (an axially rigid rod).
    """

    def __init__(self, crank, axial: bool = True):
        self.crank = crank
        self.axial = axial
        self.nq = 4 if axial else 2
        self.MQ, self.KQ, self.BQ, self.c1, self.c2, self.c12, self.c21 = _matrices(axial)

    def accelerations(self, t: float, p: np.ndarray, pd: np.ndarray, q: np.ndarray, qd: np.ndarray):
        """w = (phi1'', phi2'', x3'', q'') and lam (3,) of RESMBS's index-1 system at one state."""
        MQ, KQ, BQ, c1, c2, c12, c21 = self.MQ, self.KQ, self.BQ, self.c1, self.c2, self.c12, self.c21
        n = 3 + self.nq
        s1, c1p = np.sin(p[0]), np.cos(p[0])
        s2, c2p = np.sin(p[1]), np.cos(p[1])
        s12, c12p = np.sin(p[0] - p[1]), np.cos(p[0] - p[1])
        v1, v2 = pd[0], pd[1]
        c1q, c1qd, c2q, c2qd, c12qd = c1 @ q, c1 @ qd, c2 @ q, c2 @ qd, c12 @ qd
        A = np.zeros((n, n))
        A[0, 0] = J1 + M2 * L1 * L1
        A[0, 1] = 0.5 * L1 * L2 * M2 * c12p + RHO * L1 * (s12 * c2q + c12p * c1q)
        A[1, 1] = J2 + q @ MQ @ q + 2.0 * RHO * (c12 @ q)
        A[2, 2] = M3
        A[0, 3:] = RHO * L1 * (-s12 * c1 + c12p * c2)
        A[1, 3:] = RHO * c21 + RHO * (q @ BQ)
        A[3:, 3:] = MQ
        A = np.triu(A) + np.triu(A, 1).T
        f = np.zeros(n)
        f[0] = (-0.5 * L1 * L2 * M2 * v2 * v2 * s12 + RHO * L1 * v2 * v2 * (-s12 * c1q + c12p * c2q)
                - 2.0 * RHO * L1 * v2 * (c12p * c1qd + s12 * c2qd))
        f[1] = (0.5 * L1 * L2 * M2 * v1 * v1 * s12 + RHO * L1 * v1 * v1 * (s12 * c1q - c12p * c2q)
                - 2.0 * RHO * v2 * c12qd - 2.0 * v2 * (qd @ MQ @ q) - RHO * (qd @ BQ @ qd))
        f[3:] = (v2 * v2 * (MQ @ q) + RHO * (v2 * v2 * c12 + L1 * v1 * v1 * (c12p * c1 + s12 * c2)
                                             + 2.0 * v2 * (BQ @ qd)) - KQ @ q)
        qku, qdku = (q[3], qd[3]) if self.axial else (0.0, 0.0)
        G = np.zeros((3, n))
        G[0, 0], G[0, 1] = L1 * c1p, (L2 + qku) * c2p
        G[1, 0], G[1, 1], G[1, 2] = L1 * s1, (L2 + qku) * s2, 1.0
        G[2, 0] = 1.0
        if self.axial:
            G[0, 6], G[1, 6] = s2, -c2p
        gamma = np.array([-L1 * s1 * v1 * v1 - (L2 + qku) * s2 * v2 * v2 + 2.0 * v2 * c2p * qdku,
                          L1 * c1p * v1 * v1 + (L2 + qku) * c2p * v2 * v2 + 2.0 * v2 * s2 * qdku,
                          -self.crank(t)[2]])
        K = np.block([[A, G.T], [G, np.zeros((3, 3))]])
        sol = np.linalg.solve(K, np.concatenate([f, -gamma]))
        return sol[:n], sol[n:]

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """d/dt of y = (phi2, x3, q (nq), phi2', x3', q' (nq)); phi1 from the prescribed profile."""
        m = 2 + self.nq
        phi1, phi1_d, _ = self.crank(t)
        p = np.array([phi1, y[0], y[1]])
        pd = np.array([phi1_d, y[m], y[m + 1]])
        w, _ = self.accelerations(t, p, pd, y[2:m], y[m + 2:])
        return np.concatenate([y[m:], w[1:]])

    def solve(self, y0: np.ndarray, t_eval: np.ndarray, rtol: float = 1e-11, atol: float = 1e-14):
        """Integrate from t = 0 with DOP853; returns the solution's y at t_eval, shape (len(t_eval), 2 m)."""
        sol = solve_ivp(self.rhs, (0.0, float(t_eval[-1])), y0, method="DOP853", t_eval=t_eval,
                        rtol=rtol, atol=atol)
        if not sol.success:
            raise RuntimeError(sol.message)
        return sol.y.T


def constant_speed(t: float):
    """crank.f's prescribed crank: phi1 = OMEGA t."""
    return OMEGA * t, OMEGA, 0.0


def smooth_ramp(omega: float, duration: float):
    """phi1(t) whose rate rises from 0 to ``omega`` by the cycloidal law
    phi1_dot = omega (s - sin(2 pi s) / (2 pi)), s = t / duration, then stays at ``omega``."""
    two_pi = 2.0 * np.pi

    def crank(t: float):
        if t >= duration:
            return omega * (t - duration / 2), omega, 0.0
        s = t / duration
        angle = omega * duration * (s * s / 2 + (np.cos(two_pi * s) - 1) / two_pi**2)
        return angle, omega * (s - np.sin(two_pi * s) / two_pi), omega / duration * (1 - np.cos(two_pi * s))

    return crank


def ini1_state(axial: bool = True) -> np.ndarray:
    """INI1 as this module's y (phi1 dropped)."""
    keep = [1, 2, 3, 4, 5, 6] if axial else [1, 2, 3, 4]
    return np.concatenate([INI1[keep], INI1[[7 + k for k in keep]]])
