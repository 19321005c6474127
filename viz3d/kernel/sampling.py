"""Output samples of states: what an output frame needs from the kernel, taken inside the kernel's
one entry for output frames (``viz3d.kernel.stepping.advance_frames``), for the states it steps or
for given ones.

For each state ``(t_i, y_i, chart_i)`` (one contact memory for the whole batch): the vector field's
evaluation (kinematics, forces, multipliers), then the frames' poses and twists, the elastic
coordinates, every contact's gap, the constraint rows' multipliers, residuals and Jacobian blocks,
the rigid bodies' kinetic energy and the force elements' potential energy (their ``energy_piece``).
Nothing is allocated here: the caller hands the output arrays (``viz3d.kernel.KernelStepper.sample``).
"""

from __future__ import annotations

from viz3d.compiled import energy_piece, gap_piece, inline, jit
from viz3d.kernel.field import OK, evaluate
from viz3d.kernel.model import RIGID

try:
    from numba import literal_unroll
except ImportError:  # pragma: no cover
    def literal_unroll(x):
        return x


@inline
def sample_state(i, t, y, chart, m, v, w, forces, rows, geometry, energies, ydot, r, R, vW, wW, wB, eta, eta_dot,
                 lam, C, J, gap, T, V):
    """Row ``i`` of the outputs for the state ``(t, y, chart)`` (shapes: N states, nb + 1 bodies, n_e
    elastic coordinates, n_c rows, k contacts): ``r``, ``vW``, ``wW``, ``wB`` (N, nb + 1, 3), ``R``
    (N, nb + 1, 3, 3), ``eta``, ``eta_dot`` (N, n_e), ``lam``, ``C`` (N, n_c), ``J`` (N, n_c, 2, 6),
    ``gap`` (N, k, 11), ``T`` (N,) rigid kinetic energy [J], ``V`` (N, 2) potential energy (signed,
    non-negative) [J]; False when its evaluation failed (a mass block or the constraint matrix not
    positive definite). Inlined into the kernel's one entry for output frames,
    ``viz3d.kernel.stepping.advance_frames`` (a compiled call per frame would pass the model, the
    elements' data and the outputs flattened, more words than a small system's step), as it steps
    them or on given states; the elements' loops are compiled calls (numba inlines no function that
    uses ``literal_unroll``) that take only what they read."""
    if evaluate(t, y, chart, m, v, w, forces, rows, ydot) != OK:
        return False
    T[i] = 0.0
    for b in range(m.nb + 1):
        for a in range(3):
            r[i, b, a] = w.r[b, a]
            vW[i, b, a] = w.vW[b, a]
            wW[i, b, a] = v.wW[b, a]
            wB[i, b, a] = w.wB[b, a]
            for c in range(3):
                R[i, b, a, c] = v.R[b, a, c]
        if m.body_kind[b] == RIGID and m.mass_inv[b] > 0.0:
            s = 0.0
            for a in range(3):
                s += w.vW[b, a] * w.vW[b, a] / m.mass_inv[b]
                for c in range(3):
                    s += w.wB[b, a] * m.inertia[b, a, c] * w.wB[b, c]
            T[i] += 0.5 * s
    for e in range(m.n_e):
        eta[i, e] = w.eta[e]
        eta_dot[i, e] = w.eta_dot[e]
    for k in range(w.lam.shape[0]):
        lam[i, k] = w.lam[k]
        C[i, k] = v.C[k]
        for s_ in range(2):
            for a in range(6):
                J[i, k, s_, a] = v.J[k, s_, a]
    sample_gaps(geometry, v, gap[i])
    sample_energies(energies, v, V[i])
    return True


@jit
def sample_gaps(geometry, v, out):
    """Every contact's gap row (k, 11) from the view ``v`` (its ``gap_piece``)."""
    for d in literal_unroll(geometry):
        if d.i.shape[0] > 0:
            gap_piece(d, v, out)


@jit
def sample_energies(energies, v, out):
    """``out`` (2,) = the force elements' potential energy, signed and non-negative [J], from the view
    ``v`` (their ``energy_piece``)."""
    out[0] = 0.0
    out[1] = 0.0
    for d in literal_unroll(energies):
        if d.i.shape[0] > 0:
            energy_piece(d, v, out)
