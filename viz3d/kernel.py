"""Compiled fast path (numba) of the multibody vector field and of explicit Runge-Kutta stepping.

The NumPy implementation (dynamics.py, constraints.py, forces.py, joints.py) is the reference;
this module computes the same quantities with loops compiled by numba, because for small systems
NumPy's per-call overhead (about 50 small array operations per right-hand side) dominates.
It covers systems of ball joints, gravity, spring-dampers, applied forces/torques and sphere-plane
contacts (Hertz or linear, with a dashpot), with ZXZ
Euler angles (plain or chart-switching), the index-1 or Baumgarte formulations and any explicit
Runge-Kutta tableau; ``kernel_for`` returns None for anything else, and the caller then uses the
NumPy path. tests/numerics/test_kernel.py checks the two against each other to round-off.

Compiled with ``error_model="numpy"``: a division by zero (the Euler-angle rate map at a gimbal
lock) gives inf or nan, which the step's health check reports, as in the NumPy path; numba's
default would raise ZeroDivisionError out of the run and lose its frames.

Data layout: everything is packed by ``pack`` into flat float and int arrays once per system
(``KernelData``); the compiled functions take those arrays and the state ``y = [q, v]`` with
``chart`` (nb, 3, 3), exactly as the NumPy path (docs/notation.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

try:  # numba is optional: without it every run takes the NumPy path
    import numba
    from numba import njit
except ImportError:  # pragma: no cover - exercised only where numba is missing
    numba = None

    def njit(*args, **kwargs):
        return (lambda f: f) if not args or not callable(args[0]) else args[0]

from viz3d.coordinates import CHART_CENTRE, SINGULAR_SIN, SWITCH_SIN, EulerSwitching, EulerZXZ
from viz3d.diagnosis import MAX_COORDINATE_TURN as MAX_TURN
from viz3d.forces import AppliedForce, AppliedTorque, Gravity, SpringDamper
from viz3d.joints import BallJoint
from viz3d.timefunctions import TIME_FUNCTIONS

#: Status codes returned by ``advance``.
OK, NONFINITE, SINGULAR, SPEED, ROTATION = 0, 1, 2, 3, 4


@dataclass(frozen=True)
class KernelData:
    """A system packed into arrays for the compiled functions (see ``pack``)."""

    nb: int
    mass: np.ndarray          # (nb,)
    inertia: np.ndarray       # (nb, 3, 3)
    inertia_inv: np.ndarray   # (nb, 3, 3)
    gravity: np.ndarray       # (3,)
    joint_body: np.ndarray    # (nj, 2) int, nb = ground
    joint_s: np.ndarray       # (nj, 2, 3)
    spring_body: np.ndarray   # (ns, 2) int
    spring_s: np.ndarray      # (ns, 2, 3)
    spring_k: np.ndarray      # (ns, 3): stiffness, damping, rest length
    load_body: np.ndarray     # (nl,) int
    load_info: np.ndarray     # (nl, 3) int: torque?, body frame?, kind
    load_s: np.ndarray        # (nl, 3)
    load_f: np.ndarray        # (nl, 10): offset (3), amplitude (3), frequency, phase, start, duration
    contact_body: np.ndarray  # (nk,) int
    contact_f: np.ndarray     # (nk, 11): centre (3), radius, plane point (3), normal (3)... see pack
    perm: np.ndarray          # (n_c,) int: solve order of the rows
    pair: np.ndarray          # (n_pairs, 5) int: row, side, col, colside, slot
    kd: int
    baumgarte: np.ndarray     # (2,): alpha, beta (0, 0 for index-1)
    switching: bool


def kernel_for(system, formulation) -> KernelData | None:
    """Packed data when the kernel covers ``system`` with ``formulation``, else None."""
    if numba is None or formulation.name not in ("index1", "baumgarte") or system.bodies.flexible:
        return None
    if any(not _compiled_contacts(c, system.n_bodies) for c in system.contacts):
        return None
    if type(system.rotation) not in (EulerSwitching, EulerZXZ):
        return None
    if any(type(js) is not BallJoint for js in system.joints.joints):
        return None
    if any(type(e) not in (Gravity, SpringDamper, AppliedForce, AppliedTorque) for e in system.forces):
        return None
    return pack(system, formulation)


def _compiled_contacts(c, ground: int) -> bool:
    """The kernel covers spheres on rigid bodies against ground planes with a memoryless law, stepped through."""
    from viz3d.contact.laws import Hertz, Linear

    return (not c.located and np.all(c.body[:, 1] == ground) and not c.sides[0].flex
            and all(type(law) in (Hertz, Linear) for law in c.laws))


def pack(system, formulation) -> KernelData:
    nb = system.n_bodies
    gravity = np.zeros(3)
    springs, loads = [], []
    for e in system.forces:
        if isinstance(e, Gravity):
            gravity = gravity + e.g
        elif isinstance(e, SpringDamper):
            springs.append(e)
        else:
            loads.append(e)
    kb, kf = [], []
    for c in system.contacts:  # centre (3), radius, plane point (3), normal (3), K, exponent, damping
        for k, law in enumerate(c.laws):
            kb.append(c.body[k, 0])
            damping = law.damping if hasattr(law, "damping") else c.damping[k]
            kf.append([*c.sides[0].B_s[k], c.radius[k], *c.sides[1].B_s[k], *c.normal[k], law.stiffness,
                       getattr(law, "exponent", 1.0), damping])
    joints = system.joints.joints
    jb = np.concatenate([js.body for js in joints]) if joints else np.zeros((0, 2), int)
    js_ = np.concatenate([js.B_s for js in joints]) if joints else np.zeros((0, 2, 3))
    sb = np.concatenate([s.body for s in springs]) if springs else np.zeros((0, 2), int)
    ss = np.concatenate([s.B_s for s in springs]) if springs else np.zeros((0, 2, 3))
    sk = (np.concatenate([np.column_stack([s.stiffness, s.damping, s.rest_length]) for s in springs])
          if springs else np.zeros((0, 3)))
    lb, li, ls, lf = [], [], [], []
    for e in loads:
        tf = e.value
        for k in range(len(e.names)):
            lb.append(e.body[k])
            li.append([isinstance(e, AppliedTorque), bool(e.in_body_frame[k]), int(tf.kind[k])])
            ls.append(e.B_s[k])
            lf.append([*tf.offset[k], *tf.amplitude[k], tf.frequency[k], tf.phase[k], tf.start[k], tf.duration[k]])
    lay = system.joints
    pair = np.column_stack([lay.pair_row, lay.pair_side, lay.pair_col, lay.pair_colside, lay.pair_slot]).astype(np.int64)
    n_c = lay.n_rows
    # banded storage for any layout: a dense one is a band of half-width n_c - 1
    kd = lay.kd if lay.banded else max(n_c - 1, 0)
    if not lay.banded:
        pos = np.empty(n_c, dtype=int)
        pos[lay.perm] = np.arange(n_c)
        i, j = pos[lay.pair_row], pos[lay.pair_col]
        pair[:, 4] = (kd + i - j) * n_c + j
    ab = np.array([getattr(formulation, "alpha", 0.0), getattr(formulation, "beta", 0.0)])
    assert TIME_FUNCTIONS == ("constant", "sine", "step", "ramp", "pulse")  # the codes below
    return KernelData(
        nb, system.bodies.mass.astype(float), system.bodies.inertia.astype(float),
        system.bodies.M_inv[:nb, 3:, 3:].copy(), np.asarray(gravity, float), jb.astype(np.int64), js_.astype(float),
        sb.astype(np.int64), ss.astype(float), sk.astype(float), np.array(lb, np.int64),
        np.array(li, np.int64).reshape(-1, 3), np.array(ls, float).reshape(-1, 3), np.array(lf, float).reshape(-1, 10),
        np.array(kb, np.int64), np.array(kf, float).reshape(-1, 13),
        lay.perm.astype(np.int64), pair, int(kd), ab, isinstance(system.rotation, EulerSwitching))


def args_of(d: KernelData) -> tuple:
    """The arrays the compiled functions take, in order."""
    return (d.mass, d.inertia, d.inertia_inv, d.gravity, d.joint_body, d.joint_s, d.spring_body, d.spring_s,
            d.spring_k, d.load_body, d.load_info, d.load_s, d.load_f, d.contact_body, d.contact_f, d.perm, d.pair,
            d.kd, d.baumgarte)


# ---------------------------------------------------------------------------- compiled pieces


@njit(cache=True, error_model="numpy")
def _rot(chart, a, out):
    """out = chart @ Rz(a0) Rx(a1) Rz(a2)."""
    c1, s1 = math.cos(a[0]), math.sin(a[0])
    c2, s2 = math.cos(a[1]), math.sin(a[1])
    c3, s3 = math.cos(a[2]), math.sin(a[2])
    r = np.empty((3, 3))
    r[0, 0] = c1 * c3 - s1 * c2 * s3
    r[0, 1] = -c1 * s3 - s1 * c2 * c3
    r[0, 2] = s1 * s2
    r[1, 0] = s1 * c3 + c1 * c2 * s3
    r[1, 1] = -s1 * s3 + c1 * c2 * c3
    r[1, 2] = -c1 * s2
    r[2, 0] = s2 * s3
    r[2, 1] = s2 * c3
    r[2, 2] = c2
    for i in range(3):
        for j in range(3):
            out[i, j] = chart[i, 0] * r[0, j] + chart[i, 1] * r[1, j] + chart[i, 2] * r[2, j]


@njit(cache=True, error_model="numpy")
def _cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(cache=True, error_model="numpy")
def _mv(A, x, out):
    for i in range(3):
        out[i] = A[i, 0] * x[0] + A[i, 1] * x[1] + A[i, 2] * x[2]


@njit(cache=True, error_model="numpy")
def _mtv(A, x, out):
    for i in range(3):
        out[i] = A[0, i] * x[0] + A[1, i] * x[1] + A[2, i] * x[2]


@njit(cache=True, error_model="numpy")
def _shape(kind, t, f):
    tau = t - f[8]
    if kind == 0:
        return 0.0
    if kind == 1:
        return math.sin(2.0 * math.pi * f[6] * t + f[7])
    if kind == 2:
        return 1.0 if tau >= 0.0 else 0.0
    if kind == 3:
        if f[9] > 0.0:
            return min(max(tau / f[9], 0.0), 1.0)
        return 1.0 if tau >= 0.0 else 0.0
    return 1.0 if (tau >= 0.0 and tau < f[9]) else 0.0


@njit(cache=True, error_model="numpy")
def _banded_cholesky_solve(ab, n, kd, b):
    """Solve A x = b in place (b), A SPD in upper band storage ab[kd + i - j, j]; False if not SPD."""
    for j in range(n):
        s = ab[kd, j]
        for k in range(max(0, j - kd), j):
            u = ab[kd + k - j, j]
            s -= u * u
        if s <= 0.0:
            return False
        d = math.sqrt(s)
        ab[kd, j] = d
        for i in range(j + 1, min(n, j + kd + 1)):
            s = ab[kd + j - i, i]
            for k in range(max(0, i - kd), j):
                s -= ab[kd + k - j, j] * ab[kd + k - i, i]
            ab[kd + j - i, i] = s / d
    for i in range(n):  # U^T z = b
        s = b[i]
        for k in range(max(0, i - kd), i):
            s -= ab[kd + k - i, i] * b[k]
        b[i] = s / ab[kd, i]
    for i in range(n - 1, -1, -1):  # U x = z
        s = b[i]
        for k in range(i + 1, min(n, i + kd + 1)):
            s -= ab[kd + i - k, k] * b[k]
        b[i] = s / ab[kd, i]
    return True


@njit(cache=True, error_model="numpy")
def rhs(t, y, chart, mass, inertia, inertia_inv, gravity, joint_body, joint_s, spring_body, spring_s, spring_k,
        load_body, load_info, load_s, load_f, contact_body, contact_f, perm, pair, kd, baumgarte, ydot, ws):
    """``ydot = f(t, y)``; returns False when the constraint matrix is not positive definite.

    ``ws`` is the workspace of ``workspace``: no array is allocated here (allocation, not
    arithmetic, dominated the cost of small systems).
    """
    R, wW, vW, wB, r, F, tau, a, J, gam, C, rows_body, W, ab, x, lam, CtL, v3 = ws
    nb = mass.shape[0]
    nq = 6 * nb
    for b in range(nb + 1):
        for k in range(3):
            wW[b, k] = vW[b, k] = wB[b, k] = r[b, k] = F[b, k] = tau[b, k] = 0.0
    for b in range(nb):
        _rot(chart[b], y[6 * b + 3:6 * b + 6], R[b])
        for k in range(3):
            r[b, k] = y[6 * b + k]
            vW[b, k] = y[nq + 6 * b + k]
            wB[b, k] = y[nq + 6 * b + 3 + k]
        _mv(R[b], wB[b], wW[b])
        for k in range(3):
            F[b, k] = mass[b] * gravity[k]
    for i in range(3):
        for j in range(3):
            R[nb, i, j] = 1.0 if i == j else 0.0
    rho1, rho2, t1, t2, d, f = v3[0], v3[1], v3[2], v3[3], v3[4], v3[5]
    # spring-dampers
    for s in range(spring_body.shape[0]):
        b1, b2 = spring_body[s, 0], spring_body[s, 1]
        _mv(R[b1], spring_s[s, 0], rho1)
        _mv(R[b2], spring_s[s, 1], rho2)
        for k in range(3):
            d[k] = r[b2, k] + rho2[k] - r[b1, k] - rho1[k]
        length = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        inv = 1.0 / max(length, 1e-12)
        _cross(wW[b1], rho1, t1)
        _cross(wW[b2], rho2, t2)
        ldot = 0.0
        for k in range(3):
            ldot += d[k] * inv * (vW[b2, k] + t2[k] - vW[b1, k] - t1[k])
        for k in range(3):
            f[k] = spring_k[s, 0] * (d[k] - spring_k[s, 2] * d[k] * inv) + spring_k[s, 1] * ldot * d[k] * inv
            F[b1, k] += f[k]
            F[b2, k] -= f[k]
        _cross(rho1, f, t1)
        _cross(rho2, f, t2)
        for k in range(3):
            tau[b1, k] += t1[k]
            tau[b2, k] -= t2[k]
    # applied loads
    for i in range(load_body.shape[0]):
        b = load_body[i]
        sh = _shape(load_info[i, 2], t, load_f[i])
        for k in range(3):
            t1[k] = load_f[i, k] + load_f[i, 3 + k] * sh
        if load_info[i, 1] == 1:
            _mv(R[b], t1, t2)
            for k in range(3):
                t1[k] = t2[k]
        if load_info[i, 0] == 1:
            for k in range(3):
                tau[b, k] += t1[k]
        else:
            _mv(R[b], load_s[i], rho1)
            _cross(rho1, t1, t2)
            for k in range(3):
                F[b, k] += t1[k]
                tau[b, k] += t2[k]
    # sphere-plane contacts: F = K alpha^n + c alpha_dot >= 0 along the normal, at the deepest point
    for i in range(contact_body.shape[0]):
        b = contact_body[i]
        cf = contact_f[i]
        _mv(R[b], cf[0:3], rho1)
        alpha = cf[3]
        for k in range(3):
            alpha -= cf[7 + k] * (r[b, k] + rho1[k] - cf[4 + k])
        if alpha <= 0.0:
            continue
        for k in range(3):
            rho1[k] -= cf[3] * cf[7 + k]           # lever to the contact point
        _cross(wW[b], rho1, t1)
        adot = 0.0
        for k in range(3):
            adot -= cf[7 + k] * (vW[b, k] + t1[k])
        mag = max(cf[10] * alpha ** cf[11] + cf[12] * adot, 0.0)
        for k in range(3):
            f[k] = mag * cf[7 + k]
            F[b, k] += f[k]
        _cross(rho1, f, t2)
        for k in range(3):
            tau[b, k] += t2[k]
    # free accelerations: [F / m, I^-1 (R^T tau - w x I w)]
    for b in range(nb + 1):
        for m in range(6):
            a[b, m] = 0.0
    for b in range(nb):
        _mtv(R[b], tau[b], t1)
        _mv(inertia[b], wB[b], t2)
        _cross(wB[b], t2, d)
        for k in range(3):
            t1[k] -= d[k]
        _mv(inertia_inv[b], t1, t2)
        for k in range(3):
            a[b, k] = F[b, k] / mass[b]
            a[b, 3 + k] = t2[k]
    nj = joint_body.shape[0]
    n_c = 3 * nj
    if n_c > 0:
        for j in range(nj):
            b1, b2 = joint_body[j, 0], joint_body[j, 1]
            _mv(R[b1], joint_s[j, 0], rho1)
            _mv(R[b2], joint_s[j, 1], rho2)
            _cross(wW[b1], rho1, t1)
            _cross(wW[b1], t1, d)          # centripetal of side 1
            _cross(wW[b2], rho2, t1)
            _cross(wW[b2], t1, f)          # centripetal of side 2
            s1, s2 = joint_s[j, 0], joint_s[j, 1]
            for k in range(3):
                row = 3 * j + k
                rows_body[row, 0], rows_body[row, 1] = b1, b2
                for m in range(6):
                    J[row, 0, m] = 0.0
                    J[row, 1, m] = 0.0
                J[row, 0, k] = 1.0
                J[row, 1, k] = -1.0
                # row k of R skew(s): (R skew(s))[k, m] = sum_l R[k, l] skew(s)[l, m]
                A0, A1, A2 = R[b1, k, 0], R[b1, k, 1], R[b1, k, 2]
                J[row, 0, 3] = -(A1 * s1[2] - A2 * s1[1])
                J[row, 0, 4] = -(-A0 * s1[2] + A2 * s1[0])
                J[row, 0, 5] = -(A0 * s1[1] - A1 * s1[0])
                B0, B1, B2 = R[b2, k, 0], R[b2, k, 1], R[b2, k, 2]
                J[row, 1, 3] = B1 * s2[2] - B2 * s2[1]
                J[row, 1, 4] = -B0 * s2[2] + B2 * s2[0]
                J[row, 1, 5] = B0 * s2[1] - B1 * s2[0]
                gam[row] = f[k] - d[k]
                C[row] = r[b1, k] + rho1[k] - r[b2, k] - rho2[k]
        for row in range(n_c):
            cd = 0.0
            sa = 0.0
            for side in range(2):
                b = rows_body[row, side]
                for m in range(3):
                    sa += J[row, side, m] * a[b, m] + J[row, side, 3 + m] * a[b, 3 + m]
                    cd += J[row, side, m] * vW[b, m] + J[row, side, 3 + m] * wB[b, m]
            g = gam[row] - 2.0 * baumgarte[0] * cd - baumgarte[1] * baumgarte[1] * C[row]
            lam[row] = sa - g
            for side in range(2):
                b = rows_body[row, side]
                if b < nb:
                    for m in range(3):
                        W[row, side, m] = J[row, side, m] / mass[b]
                        W[row, side, 3 + m] = (J[row, side, 3] * inertia_inv[b, 0, m] + J[row, side, 4] * inertia_inv[b, 1, m]
                                               + J[row, side, 5] * inertia_inv[b, 2, m])
                else:
                    for m in range(6):
                        W[row, side, m] = 0.0
        for i in range(ab.shape[0]):
            ab[i] = 0.0
        for p in range(pair.shape[0]):
            val = 0.0
            for m in range(6):
                val += W[pair[p, 0], pair[p, 1], m] * J[pair[p, 2], pair[p, 3], m]
            ab[pair[p, 4]] += val
        for i in range(n_c):
            x[i] = lam[perm[i]]
        if not _banded_cholesky_solve(ab.reshape(kd + 1, n_c), n_c, kd, x):
            return False
        for i in range(n_c):
            lam[perm[i]] = x[i]
        for b in range(nb + 1):
            for m in range(6):
                CtL[b, m] = 0.0
        for row in range(n_c):
            for side in range(2):
                b = rows_body[row, side]
                for m in range(6):
                    CtL[b, m] += J[row, side, m] * lam[row]
        for b in range(nb):
            for m in range(3):
                a[b, m] -= CtL[b, m] / mass[b]
            _mv(inertia_inv[b], CtL[b, 3:6], t1)
            for m in range(3):
                a[b, 3 + m] -= t1[m]
    for b in range(nb):
        for k in range(3):
            ydot[6 * b + k] = vW[b, k]
            ydot[nq + 6 * b + k] = a[b, k]
            ydot[nq + 6 * b + 3 + k] = a[b, 3 + k]
        s2, c2 = math.sin(y[6 * b + 4]), math.cos(y[6 * b + 4])
        s3, c3 = math.sin(y[6 * b + 5]), math.cos(y[6 * b + 5])
        w1, w2, w3 = wB[b, 0], wB[b, 1], wB[b, 2]
        psi_d = (w1 * s3 + w2 * c3) / s2
        ydot[6 * b + 3] = psi_d
        ydot[6 * b + 4] = w1 * c3 - w2 * s3
        ydot[6 * b + 5] = w3 - psi_d * c2
    return True


def workspace(nb: int, n_c: int, kd: int) -> tuple:
    """Preallocated arrays of ``rhs`` (see its unpacking for the names)."""
    return (np.empty((nb + 1, 3, 3)), np.zeros((nb + 1, 3)), np.zeros((nb + 1, 3)), np.zeros((nb + 1, 3)),
            np.zeros((nb + 1, 3)), np.zeros((nb + 1, 3)), np.zeros((nb + 1, 3)), np.zeros((nb + 1, 6)),
            np.zeros((max(n_c, 1), 2, 6)), np.zeros(max(n_c, 1)), np.zeros(max(n_c, 1)),
            np.zeros((max(n_c, 1), 2), np.int64), np.zeros((max(n_c, 1), 2, 6)), np.zeros(max((kd + 1) * n_c, 1)),
            np.zeros(max(n_c, 1)), np.zeros(max(n_c, 1)), np.zeros((nb + 1, 6)), np.zeros((6, 3)))


@njit(cache=True, error_model="numpy")
def advance(n_steps, t0, h, y, chart, switches, ta, tb, tc, switching, max_speed, mass, inertia, inertia_inv,
            gravity, joint_body, joint_s, spring_body, spring_s, spring_k, load_body, load_info, load_s, load_f,
            contact_body, contact_f, perm, pair, kd, baumgarte, centre, centre_R, ws):
    """Take up to ``n_steps`` explicit RK steps in place; returns (steps done, status code).

    Between steps, bodies near gimbal lock are re-charted (``switching``) and counted in
    ``switches``; the run stops at the first non-finite state, singular constraint matrix, speed
    above ``max_speed``, or orientation coordinates that turn more than ``MAX_TURN`` rad in a
    step (plain Euler angles near gimbal lock), as ``diagnosis.check_state`` does.
    """
    n = y.shape[0]
    s = tb.shape[0]
    nb = mass.shape[0]
    k = np.empty((s, n))
    yi = np.empty(n)
    for step in range(n_steps):
        t = t0 + step * h
        for i in range(s):
            for m in range(n):
                acc = y[m]
                for j in range(i):
                    if ta[i, j] != 0.0:
                        acc += h * ta[i, j] * k[j, m]
                yi[m] = acc
            if not rhs(t + tc[i] * h, yi, chart, mass, inertia, inertia_inv, gravity, joint_body, joint_s, spring_body,
                       spring_s, spring_k, load_body, load_info, load_s, load_f, contact_body, contact_f, perm, pair, kd,
                       baumgarte, k[i], ws):
                return step, SINGULAR
        for m in range(n):
            acc = y[m]
            for i in range(s):
                if tb[i] != 0.0:
                    acc += h * tb[i] * k[i, m]
            y[m] = acc
        for m in range(n):
            if not math.isfinite(y[m]):
                return step + 1, NONFINITE
        nq = 6 * nb
        for b in range(nb):
            sp = math.sqrt(y[nq + 6 * b] ** 2 + y[nq + 6 * b + 1] ** 2 + y[nq + 6 * b + 2] ** 2)
            if sp > max_speed:
                return step + 1, SPEED
            st = abs(math.sin(y[6 * b + 4]))
            # as diagnosis.check_state: orientation coordinates turning over MAX_TURN rad in a step
            s3, c3 = math.sin(y[6 * b + 5]), math.cos(y[6 * b + 5])
            w1, w2, w3 = y[nq + 6 * b + 3], y[nq + 6 * b + 4], y[nq + 6 * b + 5]
            psi_d = (w1 * s3 + w2 * c3) / st if st > 0.0 else math.inf
            turn = max(abs(psi_d), abs(w1 * c3 - w2 * s3), abs(w3 - psi_d * math.cos(y[6 * b + 4]))) * h
            if turn > MAX_TURN or (not switching and st < SINGULAR_SIN):
                return step + 1, ROTATION
            if switching and st < SWITCH_SIN:
                R = ws[0][nb]  # scratch (ground's slot is reset by the next rhs)
                _rot(chart[b], y[6 * b + 3:6 * b + 6], R)
                for i in range(3):
                    for j in range(3):  # chart = R @ R_centre^T
                        chart[b, i, j] = R[i, 0] * centre_R[j, 0] + R[i, 1] * centre_R[j, 1] + R[i, 2] * centre_R[j, 2]
                y[6 * b + 3], y[6 * b + 4], y[6 * b + 5] = centre[0], centre[1], centre[2]
                switches[b] += 1
    return n_steps, OK


def _workspace(data: KernelData) -> tuple:
    return workspace(data.nb, 3 * data.joint_body.shape[0], data.kd)


def kernel_rhs(data: KernelData, t: float, y: np.ndarray, chart: np.ndarray) -> np.ndarray:
    """The compiled right-hand side (for tests and diagnostics)."""
    out = np.empty_like(y)
    if not rhs(t, y, chart, *args_of(data), out, _workspace(data)):
        raise np.linalg.LinAlgError("constraint matrix is not positive definite")
    return out


class CompiledField:
    """A ``dynamics.VectorField`` whose evaluations run in the kernel (same interface)."""

    def __init__(self, field, data: KernelData, ws: tuple):
        self.field, self.ws, self.args = field, ws, args_of(data)
        self.n_q, self.chart = field.n_q, field.chart

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        self.field.n_evals += 1
        out = np.empty_like(y)
        if not rhs(t, y, self.chart, *self.args, out, self.ws):
            return self.field(t, y)  # the NumPy path raises the detailed error
        return out

    def retract(self, q, w):
        return self.field.retract(q, w)


class KernelStepper:
    """Explicit RK steps of one system through the kernel, with the workspace allocated once."""

    def __init__(self, data: KernelData, tableau):
        from viz3d.rotations import matrix_from_euler

        self.data, self.tableau = data, tableau
        self.args = args_of(data)
        self.ws = _workspace(data)
        self.centre, self.centre_R = CHART_CENTRE.copy(), matrix_from_euler(CHART_CENTRE)

    def step(self, t: float, h: float, y: np.ndarray, chart: np.ndarray, switches: np.ndarray,
             max_speed: float, n_steps: int = 1) -> tuple[int, int]:
        """``n_steps`` steps of ``y``, ``chart`` in place; returns (steps done, status code, ``OK`` =
        0). On a failure ``y`` holds the failed step's result."""
        tab = self.tableau
        return advance(n_steps, t, h, y, chart, switches, tab.a, tab.b, tab.c, self.data.switching, max_speed,
                       *self.args, self.centre, self.centre_R, self.ws)


def kernel_advance(data: KernelData, tableau, n_steps: int, t0: float, h: float, y: np.ndarray, chart: np.ndarray,
                   switches: np.ndarray, max_speed: float) -> tuple[int, int]:
    """Advance ``y`` and ``chart`` in place by up to ``n_steps`` steps; (steps done, status)."""
    return KernelStepper(data, tableau).step(t0, h, y, chart, switches, max_speed, n_steps)
