"""Independent references for the tests: written without any viz3d code.

* ``fixed_point_body``: a rigid body turning about a fixed point (top, pendulum) integrated with
  scipy's DOP853 in unit quaternions + body angular velocity about the pivot - a reduced,
  unconstrained formulation unlike viz3d's constrained one.
* ``torque_free_omega``: Euler's torque-free equations in closed form (Jacobi elliptic
  functions, Landau & Lifshitz, Mechanics, sec. 37).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation
from scipy.special import ellipj, ellipkinc

RTOL = 1e-11
ATOL = 1e-12


def _quat_mul(p, q):
    pw, pv = p[0], p[1:]
    qw, qv = q[0], q[1:]
    return np.concatenate([[pw * qw - pv @ qv], pw * qv + qw * pv + np.cross(pv, qv)])


def fixed_point_body(I_G, m, c_B, g, R0, W_omega0, t_eval, rtol=RTOL, atol=ATOL):
    """Body with a fixed point at the world origin.

    Parameters
    ----------
    I_G : (3, 3) inertia about the centre of mass, body axes [kg m^2]
    m : mass [kg]
    c_B : (3,) centre of mass from the pivot, body axes [m]
    g : (3,) gravity [m/s^2]
    R0 : (3, 3) initial world-from-body rotation
    W_omega0 : (3,) initial angular velocity, world axes [rad/s]
    t_eval : (n,) output times [s]

    Returns
    -------
    R : (n, 3, 3) rotations, W_omega : (n, 3), W_rG : (n, 3) centre-of-mass positions
    """
    c_B = np.asarray(c_B, float)
    I_O = np.asarray(I_G, float) + m * (c_B @ c_B * np.eye(3) - np.outer(c_B, c_B))
    I_O_inv = np.linalg.inv(I_O)

    def rhs(t, y):
        quat, w = y[:4], y[4:]
        R = Rotation.from_quat(quat, scalar_first=True).as_matrix()
        tau = np.cross(c_B, R.T @ (m * np.asarray(g)))
        w_dot = I_O_inv @ (tau - np.cross(w, I_O @ w))
        q_dot = 0.5 * _quat_mul(quat, np.concatenate([[0.0], w]))
        # keep |quat| = 1 exactly along the flow (the projection term vanishes on the manifold)
        q_dot -= (quat @ quat - 1.0) * quat
        return np.concatenate([q_dot, w_dot])

    q0 = Rotation.from_matrix(R0).as_quat(scalar_first=True)
    y0 = np.concatenate([q0, R0.T @ np.asarray(W_omega0, float)])
    sol = solve_ivp(rhs, (t_eval[0], t_eval[-1]), y0, method="DOP853", t_eval=t_eval, rtol=rtol, atol=atol)
    assert sol.success, sol.message
    R = Rotation.from_quat(sol.y[:4].T, scalar_first=True).as_matrix()
    W_omega = np.einsum("nij,jn->ni", R, sol.y[4:])
    return R, W_omega, R @ c_B


def torque_free_omega(I_principal, omega0, t):
    """Body-axis angular velocity of a torque-free body in its principal axes, closed form.

    Parameters
    ----------
    I_principal : (3,) distinct principal moments in increasing order
    omega0 : (3,) initial angular velocity in those principal axes [rad/s]
    t : (n,) times [s]

    Returns
    -------
    (n, 3) angular velocity in principal axes.
    """
    I = np.asarray(I_principal, float)
    w0 = np.asarray(omega0, float)
    assert I[0] < I[1] < I[2]
    two_E = I @ w0**2
    M2 = (I**2) @ w0**2
    if M2 < two_E * I[1]:
        return _about_smallest_axis(I, w0, t, two_E, M2)
    return _landau(I, w0, t, two_E, M2)


def _landau(I, w0, t, two_E, M2):
    """M^2 > 2E I2: circulation about the largest axis; omega_3 keeps its sign."""
    I1, I2, I3 = I
    A1 = np.sqrt((two_E * I3 - M2) / (I1 * (I3 - I1)))
    A2 = np.sqrt((two_E * I3 - M2) / (I2 * (I3 - I2)))
    A3 = np.sqrt((M2 - two_E * I1) / (I3 * (I3 - I1)))
    rate = np.sqrt((I3 - I2) * (M2 - two_E * I1) / (I1 * I2 * I3))
    k2 = (I2 - I1) * (two_E * I3 - M2) / ((I3 - I2) * (M2 - two_E * I1))
    s = np.sign(w0[2])
    tau0 = ellipkinc(np.arctan2(s * w0[1] / A2, w0[0] / A1), k2)
    sn, cn, dn, _ = ellipj(rate * np.asarray(t) + tau0, k2)
    return np.stack([A1 * cn, s * A2 * sn, s * A3 * dn], axis=1)


def _about_smallest_axis(I, w0, t, two_E, M2):
    """M^2 < 2E I2: suffixes 1 and 3 interchanged; omega_1 keeps its sign."""
    I1, I2, I3 = I
    A1 = np.sqrt((two_E * I3 - M2) / (I1 * (I3 - I1)))
    A2 = np.sqrt((M2 - two_E * I1) / (I2 * (I2 - I1)))
    A3 = np.sqrt((M2 - two_E * I1) / (I3 * (I3 - I1)))
    rate = np.sqrt((I2 - I1) * (two_E * I3 - M2) / (I1 * I2 * I3))
    k2 = (I3 - I2) * (M2 - two_E * I1) / ((I2 - I1) * (two_E * I3 - M2))
    s = np.sign(w0[0])
    tau0 = ellipkinc(np.arctan2(w0[1] / A2, s * w0[2] / A3), k2)
    sn, cn, dn, _ = ellipj(rate * np.asarray(t) + tau0, k2)
    return np.stack([s * A1 * dn, A2 * sn, s * A3 * cn], axis=1)
