"""The free one-degree-of-freedom impact ``m_eff alpha_ddot = -F(alpha, alpha_dot)`` through one contact.

What a normal law really does with a given effective mass and approach speed: restitution,
duration, peak force and indentation, energy lost, and the sampled history for energy ledgers.
Integrated with scipy's DOP853 at tight tolerances; conventions of ``viz3d.contact.laws``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from viz3d._typing import FloatArray

if TYPE_CHECKING:
    from viz3d.contact.laws import ContactMemory, NormalLaw

#: Relative tolerance of DOP853 (near its double-precision floor).
RTOL = 1e-12
#: Absolute tolerances as fractions of the natural scales (indentation, speed, energy).
ATOL_FRACTION = 1e-14
#: Integration window, in units of the time scale alpha*/v0, before a phase is declared endless.
MAX_PHASE_TIMES = 1e4
#: Samples per phase kept in the history (and scanned for the force peak).
N_SAMPLES = 400
#: Bisection steps locating the last instant of non-zero force (2^-80 of the phase length).
N_BISECT = 80


@dataclass(frozen=True)
class ImpactHistory:
    """Sampled 1-DOF impact, compression then restitution (times strictly increasing).

    Attributes
    ----------
    t : ndarray, shape (n,) [s]
    alpha : ndarray, shape (n,) [m]
    alpha_dot : ndarray, shape (n,) [m/s]
    force : ndarray, shape (n,) [N]
    work : ndarray, shape (n,)
        Work done on the contact, ``integral of F alpha_dot dt`` (integrated with the motion) [J].
    elastic_energy : ndarray, shape (n,)
        ``law.elastic_energy`` with the memory of that instant [J].
    """

    t: FloatArray
    alpha: FloatArray
    alpha_dot: FloatArray
    force: FloatArray
    work: FloatArray
    elastic_energy: FloatArray

    @property
    def dissipated(self) -> FloatArray:
        """Energy dissipated so far, ``work - elastic_energy`` [J], shape (n,)."""
        return self.work - self.elastic_energy


@dataclass(frozen=True)
class ImpactOutcome:
    """Result of one 1-DOF impact.

    Attributes
    ----------
    restitution : float
        ``-alpha_dot_out / alpha_dot_in``.
    duration : float
        Time during which the force is non-zero [s].
    time_max_compression : float
        Instant of ``alpha_dot = 0`` [s].
    peak_force : float [N]
    peak_indentation : float [m]
    residual_indentation : float [m]
    energy_in : float
        ``m_eff v0^2 / 2`` [J].
    energy_lost : float
        ``m_eff (v0^2 - v_out^2) / 2`` [J].
    work : float
        Work done on the contact over the impact, integrated independently of the velocity [J].
    memory : ContactMemory
        Contact memory at the end.
    history : ImpactHistory
    """

    restitution: float
    duration: float
    time_max_compression: float
    peak_force: float
    peak_indentation: float
    residual_indentation: float
    energy_in: float
    energy_lost: float
    work: float
    memory: ContactMemory
    history: ImpactHistory


def achieved_restitution(law: NormalLaw, m_eff: float, v0: float, memory: ContactMemory | None = None) -> ImpactOutcome:
    """The restitution a law really gives: integrate the free 1-DOF impact ``m_eff alpha_ddot = -F``
    from ``alpha = 0``, ``alpha_dot = v0 > 0`` until the bodies part (scipy DOP853, rtol 1e-12).

    ``m_eff = m1 m2 / (m1 + m2)`` [kg]; ``memory``: history from earlier contacts (elastoplastic
    laws keep their crater). Returns the restitution ``-alpha_dot_out / alpha_dot_in``, contact
    duration, peak force and indentation, energies, residual indentation and the sampled history.

    Two phases: compression to ``alpha_dot = 0`` (the memory is updated there, so the force is exact
    for every law: ``alpha`` is monotonic in each phase) and restitution until ``alpha`` is back to
    0 (after the force has vanished the motion is free, so the exit speed is the separation speed).
    """
    if v0 <= 0.0 or m_eff <= 0.0:
        raise ValueError(f"need v0 > 0 and m_eff > 0, got v0={v0}, m_eff={m_eff}")
    mem0 = law.onset(v0, memory)
    scale = _scales(law, mem0, m_eff, v0)
    sol1 = _phase(law, mem0, m_eff, 0.0, np.array([0.0, v0, 0.0]), scale, "compression")
    t_mc, y_mc = sol1.t_events[0][0], sol1.y_events[0][0]
    mem1 = law.update(mem0, y_mc[0], 0.0)
    sol2 = _phase(law, mem1, m_eff, t_mc, np.array([y_mc[0], 0.0, y_mc[2]]), scale, "restitution")
    t_out, y_out = sol2.t_events[0][0], sol2.y_events[0][0]
    history = _history(law, (mem0, mem1), (sol1, sol2), (t_mc, t_out))
    return ImpactOutcome(
        restitution=float(-y_out[1] / v0),
        duration=_last_contact_time(law, mem1, sol2, t_mc, t_out),
        time_max_compression=float(t_mc),
        peak_force=_peak_force(law, (mem0, mem1), (sol1, sol2), history),
        peak_indentation=float(y_mc[0]),
        residual_indentation=mem1.alpha_residual,
        energy_in=0.5 * m_eff * v0**2,
        energy_lost=0.5 * m_eff * (v0**2 - y_out[1] ** 2),
        work=float(y_out[2]),
        memory=law.update(mem1, 0.0, y_out[1]),
        history=history,
    )


def _scales(law, memory, m_eff, v0):
    """Indentation, speed, energy and time scales: ``alpha*`` stores the impact's kinetic energy."""
    from scipy.optimize import brentq
    energy = 0.5 * m_eff * v0**2

    def excess(alpha):
        return law.elastic_energy(alpha, law.update(memory, alpha, v0)) - energy

    hi = 1e-15
    while excess(hi) < 0.0:
        hi *= 10.0
        if hi > 1e6:
            raise ValueError(f"{law.name}: no indentation below 1e6 m stores {energy} J; is the stiffness zero?")
    alpha_star = brentq(excess, 0.0, hi, rtol=1e-6)
    return {"alpha": alpha_star, "v": v0, "energy": energy, "time": alpha_star / v0}


def _phase(law, memory, m_eff, t0, y0, scale, which):
    """One monotonic phase; stops at ``alpha_dot = 0`` (compression) or ``alpha = 0`` (restitution)."""
    from scipy.integrate import solve_ivp

    def rhs(t, y):
        F = law.force(y[0], y[1], memory)
        return [y[1], -F / m_eff, F * y[1]]

    def turning(t, y):
        return y[1]

    def exit_(t, y):
        return y[0]

    event = turning if which == "compression" else exit_
    event.terminal, event.direction = True, -1.0
    atol = ATOL_FRACTION * np.array([scale["alpha"], scale["v"], scale["energy"]])
    t_end = t0 + MAX_PHASE_TIMES * scale["time"]
    sol = solve_ivp(rhs, (t0, t_end), y0, method="DOP853", rtol=RTOL, atol=atol, events=event, dense_output=True)
    if sol.status != 1:
        raise RuntimeError(f"{law.name}: {which} did not end within {t_end - t0:.3g} s ({sol.message})")
    return sol


def _history(law, memories, sols, bounds):
    """Samples of both phases; the compression memory follows alpha (alpha_max = alpha)."""
    t1 = np.linspace(0.0, bounds[0], N_SAMPLES, endpoint=False)
    t2 = np.linspace(bounds[0], bounds[1], N_SAMPLES)
    cols = []
    for t, sol, mem in zip((t1, t2), sols, memories):
        y = sol.sol(t)
        mems = [law.update(mem, a, ad) for a, ad in zip(y[0], y[1])]
        F = np.array([law.force(a, ad, mem) for a, ad in zip(y[0], y[1])])
        E = np.array([law.elastic_energy(a, m) for a, m in zip(y[0], mems)])
        cols.append((t, y[0], y[1], F, y[2], E))
    return ImpactHistory(*(np.concatenate(parts) for parts in zip(*cols)))


def _last_contact_time(law, memory, sol, t_mc, t_out):
    """Last instant of non-zero force (bisection: after it the force stays zero, the motion is free)."""
    lo, hi = t_mc, t_out
    for _ in range(N_BISECT):
        mid = 0.5 * (lo + hi)
        a, ad = sol.sol(mid)[:2]
        if law.force(a, ad, memory) > 0.0:
            lo = mid
        else:
            hi = mid
    return float(hi)


def _peak_force(law, memories, sols, history):
    """Largest force: best sample, refined by a bounded scalar search around it."""
    from scipy.optimize import minimize_scalar
    i = int(np.argmax(history.force))
    lo, hi = history.t[max(i - 1, 0)], history.t[min(i + 1, len(history.t) - 1)]
    t_mc = sols[1].t[0]
    k = 0 if history.t[i] < t_mc else 1
    lo, hi = (lo, min(hi, t_mc)) if k == 0 else (max(lo, t_mc), hi)  # stay inside one phase

    def minus_force(t):
        a, ad = sols[k].sol(t)[:2]
        return -law.force(a, ad, memories[k])

    if hi <= lo:
        return float(history.force[i])
    best = minimize_scalar(minus_force, bounds=(lo, hi), method="bounded", options={"xatol": 1e-12 * hi})
    return float(max(-best.fun, history.force[i]))
