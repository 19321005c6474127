"""Constrained dynamics against sympy.physics.mechanics: a spatial double pendulum on ball joints
with general (non-principal) inertia tensors, derived by Kane's method in minimal coordinates
(ZXZ angles, body angular velocity components as generalized speeds) - no constraint equations,
no multipliers, none of viz3d's code. Accelerations are compared at random states."""

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from viz3d.bodies import Bodies
from viz3d.constraints import build_layout
from viz3d.coordinates import EulerSwitching
from viz3d.dynamics import accelerations
from viz3d.forces import Gravity
from viz3d.formulation import Index1
from viz3d.joints import BallJoint
from viz3d.rotations import matrix_from_euler
from viz3d.system import System

from systems import random_inertia

G = 9.81
#: Each side solves a mass matrix (Kane's 6x6 here, viz3d's augmented system there) by a backward-stable
#: method: each within ~ p(n) eps cond(M) |qdd| of the exact accelerations (Higham, thm. 7.2), p(n) taken
#: as 10; cond is that of Kane's mass matrix (~300; seen differences ~1.5 eps cond).
SOLVE_SAFETY = 10.0
#: Positions are built from the joints through three rotation products of O(1) entries: |C| ~ a few eps m.
JOINT_ROUNDOFF = 1e-14


@pytest.fixture(scope="module")
def pendulum():
    """Numeric parameters and the lambdified Kane equations of the double pendulum."""
    rng = np.random.default_rng(7)
    m = rng.uniform(0.5, 2.0, 2)
    I = random_inertia(rng, 2)
    s1 = rng.normal(scale=0.3, size=3)    # body 1: centre of mass -> pivot (ground origin)
    e1 = rng.normal(scale=0.3, size=3)    # body 1: centre of mass -> elbow
    s2 = rng.normal(scale=0.3, size=3)    # body 2: centre of mass -> elbow
    q, u = me.dynamicsymbols("q1:7"), me.dynamicsymbols("u1:7")
    N, A, B = me.ReferenceFrame("N"), me.ReferenceFrame("A"), me.ReferenceFrame("B")
    A.orient_body_fixed(N, q[0:3], "ZXZ")
    B.orient_body_fixed(N, q[3:6], "ZXZ")
    kd = [me.dot(A.ang_vel_in(N), A.x) - u[0], me.dot(A.ang_vel_in(N), A.y) - u[1], me.dot(A.ang_vel_in(N), A.z) - u[2],
          me.dot(B.ang_vel_in(N), B.x) - u[3], me.dot(B.ang_vel_in(N), B.y) - u[4], me.dot(B.ang_vel_in(N), B.z) - u[5]]
    A.set_ang_vel(N, u[0] * A.x + u[1] * A.y + u[2] * A.z)
    B.set_ang_vel(N, u[3] * B.x + u[4] * B.y + u[5] * B.z)

    def vec(frame, x):
        return sum((float(c) * d for c, d in zip(x, (frame.x, frame.y, frame.z))), me.Vector(0))

    O = me.Point("O")
    O.set_vel(N, 0)
    G1 = O.locatenew("G1", -vec(A, s1))
    G1.v2pt_theory(O, N, A)
    E = G1.locatenew("E", vec(A, e1))
    E.v2pt_theory(G1, N, A)
    G2 = E.locatenew("G2", -vec(B, s2))
    G2.v2pt_theory(E, N, B)

    def dyadic(frame, T):
        return me.inertia(frame, *(float(T[i, j]) for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (2, 0))))

    bodies = [me.RigidBody("b1", G1, A, float(m[0]), (dyadic(A, I[0]), G1)),
              me.RigidBody("b2", G2, B, float(m[1]), (dyadic(B, I[1]), G2))]
    loads = [(G1, -float(m[0]) * G * N.z), (G2, -float(m[1]) * G * N.z)]
    kane = me.KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=kd)
    kane.kanes_equations(bodies, loads)
    args = list(q) + list(u)
    mass = sp.lambdify(args, kane.mass_matrix, "numpy")
    forcing = sp.lambdify(args, kane.forcing, "numpy")
    return dict(m=m, I=I, s1=s1, e1=e1, s2=s2, mass=mass, forcing=forcing)


def _viz3d_system(p):
    bodies = Bodies(("b1", "b2"), p["m"], p["I"])
    joints = BallJoint(("pivot", "elbow"), np.array([[0, 2], [1, 0]]),
                       np.array([[p["s1"], np.zeros(3)], [p["s2"], p["e1"]]]))
    return System(bodies, build_layout((joints,), 2), (Gravity(p["m"], np.array([0.0, 0.0, -G])),), EulerSwitching())


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_double_pendulum_accelerations_match_kanes_method(pendulum, seed):
    p = pendulum
    rng = np.random.default_rng(100 + seed)
    angles = np.column_stack([rng.uniform(-3, 3, 2), rng.uniform(0.3, 2.8, 2), rng.uniform(-3, 3, 2)])
    B_omega = rng.normal(scale=3.0, size=(2, 3))
    R = matrix_from_euler(angles)
    # positions and velocities that satisfy the joints (the minimal model has no other kind)
    W_w = np.einsum("bij,bj->bi", R, B_omega)
    r1 = -R[0] @ p["s1"]
    elbow = r1 + R[0] @ p["e1"]
    r2 = elbow - R[1] @ p["s2"]
    v1 = np.cross(W_w[0], r1)
    v2 = np.cross(W_w[0], elbow) + np.cross(W_w[1], r2 - elbow)
    system = _viz3d_system(p)
    q = system.join_q(np.array([r1, r2]), angles)
    v = np.concatenate([v1, B_omega[0], v2, B_omega[1]])
    acc = accelerations(system, Index1(), 0.0, q, v, np.stack([np.eye(3)] * 2))
    ours = acc.v_dot.reshape(2, 6)[:, 3:].reshape(-1)
    args = list(angles[0]) + list(angles[1]) + list(B_omega.reshape(-1))
    mass = np.asarray(p["mass"](*args), float)
    theirs = np.linalg.solve(mass, np.asarray(p["forcing"](*args), float).ravel())
    tol = 2 * SOLVE_SAFETY * np.finfo(float).eps * np.linalg.cond(mass, np.inf) * np.abs(theirs).max()
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=tol, err_msg="mismatch: B_omega_dot")
    assert np.max(np.abs(acc.rows.C)) < JOINT_ROUNDOFF
