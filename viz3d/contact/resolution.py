"""What a normal law allows, and how finely a contact must be resolved in time.

Pieces an event-driven integrator needs for any normal law of ``viz3d.contact.laws``, whatever
bodies carry it; the bodies enter only through

* the effective mass of the contact, ``m_eff = 1 / (r1^T M1^-1 r1 + r2^T M2^-1 r2)`` [kg] (the
  contact points' velocity change per unit impulse, summed over both bodies, inverted);
* the approach speed at onset ``v`` [m/s] and a quasi-static force the loads press with [N];
* the energy available to the contact [J].

``contact_time_scale`` bounds the step during a contact; ``admissible_indentation`` is the deepest
indentation whose recoverable energy the available energy can pay for; ``free_impact_restitution``
is the restitution a law gives in a free one-degree-of-freedom impact (rigid bodies, no loads),
exact for every law. ``indentation_diagnosis`` and ``restitution_diagnosis`` turn violations
into the sentence a run stops with. Conventions and units as in ``viz3d.contact.laws``.
"""

from __future__ import annotations

import numpy as np

from viz3d.contact.laws import MIN_APPROACH_SPEED, ContactMemory, HysteresisLaw, Linear, NormalLaw
from viz3d.contact.parameters import hysteresis_restitution, linear_restitution
from viz3d.contact.single_impact import achieved_restitution

#: Largest step during a contact, as a fraction of its time scale (a half period): with 20 steps per
#: half period the cubic Hermite interpolant on which onset, maximum indentation and separation are
#: located is within (pi/20)^4 / 384 = 1.6e-6 of a harmonic motion's amplitude, whatever rtol asks.
STEP_FRACTION = 1.0 / 20.0
#: Smallest indentation tried when bracketing a root [m] (far below any atomic scale).
ALPHA_FLOOR = 1e-15
#: Bracketing stops here [m]: no law stores a joule below a kilometre of indentation.
ALPHA_CEILING = 1e3
#: Relative precision of the indentations found by root finding.
ALPHA_RTOL = 1e-10


def loaded(law: NormalLaw, memory: ContactMemory | None, alpha: float, speed: float = 0.0) -> ContactMemory:
    """Memory of a contact that started at ``speed`` [m/s] and has loaded to ``alpha`` [m]."""
    mem = law.onset(speed, memory)
    return law.update(mem, alpha, 1.0)


def recoverable_energy(law: NormalLaw, alpha: float, memory: ContactMemory | None = None) -> float:
    """Energy the contact would give back after loading to ``alpha`` [J] (0 inside the crater)."""
    return float(law.elastic_energy(alpha, loaded(law, memory, alpha)))


def admissible_indentation(law: NormalLaw, energy: float, memory: ContactMemory | None = None) -> float:
    """Deepest indentation [m] whose recoverable energy does not exceed ``energy`` [J].

    Whatever the bodies do, the work done on the contact is its recoverable energy plus what it
    dissipated (>= 0), and that work cannot exceed the energy available to the contact: the
    bodies' kinetic and strain energy at onset plus the work of the loads since. A crater left by
    earlier contacts (``memory.alpha_residual``) costs nothing to re-enter.
    """
    crater = 0.0 if memory is None else float(memory.alpha_residual)
    if energy <= 0.0:
        return crater
    return _first_root(lambda a: recoverable_energy(law, a, memory) - energy, crater)


def quasi_static_indentation(law: NormalLaw, force: float, memory: ContactMemory | None = None) -> float:
    """Indentation [m] at which the law, loaded slowly, carries ``force`` [N]."""
    crater = 0.0 if memory is None else float(memory.alpha_residual)
    if force <= 0.0:
        return crater
    return _first_root(lambda a: float(law.force(a, 0.0, loaded(law, memory, a))) - force, crater)


def _first_root(excess, crater: float) -> float:
    """Root of ``excess``, increasing from <= 0 at ``crater``: bracketed by doubling the depth
    below the crater from ``ALPHA_FLOOR``, then refined (``inf`` beyond ``ALPHA_CEILING``)."""
    from scipy.optimize import brentq
    depth = ALPHA_FLOOR
    while excess(crater + depth) <= 0.0:
        depth *= 2.0
        if depth > ALPHA_CEILING:
            return np.inf
    lo = crater + depth / 2.0 if depth > ALPHA_FLOOR else crater
    return float(brentq(excess, lo, crater + depth, rtol=ALPHA_RTOL, xtol=1e-300))


def contact_time_scale(law: NormalLaw, m_eff: float, speed: float, memory: ContactMemory | None = None,
                       force: float = 0.0) -> float:
    """Half period of the contact's secant stiffness at its largest indentation [s].

    The largest indentation ``alpha_m`` is the deeper of the one whose recoverable energy equals
    the approach kinetic energy ``m_eff v^2 / 2`` and the quasi-static one under ``force``; the
    secant stiffness is ``k = F(alpha_m, v) / (alpha_m - alpha_r)``, with the rate term of the
    law at the approach speed (stiffer, so the estimate errs short), and ``t = pi sqrt(m_eff / k)``.
    Linear law: the exact contact duration ``pi sqrt(m/K)``; Hertz: ``pi sqrt(4/5) alpha_m / v =
    2.81 alpha_m / v`` against the exact 2.9433 alpha_m / v. ``inf`` when nothing presses, and for
    an infinite ``m_eff`` (the joints hold the bodies along the normal: nothing moves into the contact).

    Parameters
    ----------
    law : NormalLaw
    m_eff : float
        Effective mass of the contact [kg].
    speed : float
        Approach speed at onset [m/s].
    memory : ContactMemory, optional
        History before this contact (a crater).
    force : float
        Force the loads press the surfaces together with [N] (0 if none).
    """
    if m_eff == np.inf:
        return np.inf
    crater = 0.0 if memory is None else float(memory.alpha_residual)
    alpha_m = max(admissible_indentation(law, 0.5 * m_eff * speed**2, memory),
                  quasi_static_indentation(law, force, memory))
    if not np.isfinite(alpha_m) or alpha_m <= crater:
        return np.inf
    F = float(law.force(alpha_m, speed, loaded(law, memory, alpha_m, speed)))
    if F <= 0.0:
        return np.inf
    return float(np.pi * np.sqrt(m_eff * (alpha_m - crater) / F))


def free_impact_restitution(law: NormalLaw, m_eff: float, speed: float, memory: ContactMemory | None = None) -> float:
    """Restitution the law gives a free one-degree-of-freedom impact ``m_eff alpha_dd = -F`` at ``speed``.

    Closed forms where they exist (elastic: 1; hysteresis laws: ``hysteresis_restitution(chi)``
    whatever mass and speed, as long as the law sees the true approach speed, i.e. above
    ``MIN_APPROACH_SPEED``; with a fixed ``damping_factor`` c, ``chi = c speed``; the no-tension
    linear dashpot: ``linear_restitution(zeta)``),
    otherwise the law integrated through the contact (``single_impact.achieved_restitution``).
    """
    if not law.dissipative:
        return 1.0
    if isinstance(law, HysteresisLaw) and law.damping_factor > 0.0:  # chi = c v0 at this speed
        return hysteresis_restitution(law.damping_factor * speed)
    if isinstance(law, HysteresisLaw) and speed >= MIN_APPROACH_SPEED:
        return hysteresis_restitution(law.factor())
    if isinstance(law, Linear):
        return linear_restitution(law.damping / (2.0 * np.sqrt(law.stiffness * m_eff)))
    return achieved_restitution(law, m_eff, speed, memory).restitution


def load_restitution_slack(load_acceleration: float, duration: float, speed: float) -> float:
    """How far a constant load can move a contact's restitution from its free value.

    The load changes the relative speed by at most ``|a| t`` over the contact of duration ``t``, a
    relative perturbation ``|a| t / v`` of the motion the law sees on the way in and again on the
    way out: ``2 |a| t / v``.
    """
    return 2.0 * abs(load_acceleration) * duration / speed if speed > 0.0 else np.inf


def integration_restitution_slack(velocity_error: float, speed: float) -> float:
    """Bound on the restitution error of the steps taken during a contact.

    ``velocity_error`` [m/s] sums the magnitudes of the embedded error estimates of the relative
    normal velocity over the contact's accepted steps: each is the local error of the lower-order
    solution, an upper bound (asymptotically in the step) of the propagated solution's; summed
    without amplification and divided by the approach speed ``speed`` [m/s].
    """
    if speed <= 0.0:
        return np.inf
    return velocity_error / speed


def indentation_diagnosis(index: int, t: float, alpha: float, law: NormalLaw, energy: float,
                          memory: ContactMemory | None, detail: str = "") -> str:
    """Why a run stops when contact ``index`` (1-based) reached ``alpha`` [m] at ``t`` [s] with only
    ``energy`` [J] available (``detail`` says where that energy came from)."""
    allowed = admissible_indentation(law, energy, memory)
    return (f"contact {index} at t = {t:.6g} s: indentation {alpha:.3g} m exceeds the {allowed:.2g} m the "
            f"{law.name} law allows with the energy available ({energy:.3g} J{': ' + detail if detail else ''}); "
            f"the contact was not resolved (reduce sim.rtol or sim.max_step)")


def energy_diagnosis(index: int, t: float, created: float, allowed: float, n_steps: int) -> str:
    """Why a run stops when the numerics created ``created`` [J] during contact ``index`` (1-based)
    up to ``t`` [s], more than the ``allowed`` [J] the error estimates of its ``n_steps`` steps admit."""
    return (f"contact {index} at t = {t:.6g} s: energy {created:.3g} J created by the integration since the contact "
            f"began exceeds the {allowed:.3g} J the error estimates of its {n_steps} steps allow; "
            f"the contact was not resolved (reduce sim.rtol or sim.max_step)")


def restitution_diagnosis(index: int, t: float, restitution: float, low: float, high: float, law: NormalLaw,
                          approach: float, separation: float) -> str | None:
    """None when ``low <= restitution <= high``, else why a run stops at the end of contact ``index``."""
    if low <= restitution <= high:
        return None
    return (f"contact {index} at t = {t:.6g} s: restitution {restitution:.4g} outside the [{low:.4g}, {high:.4g}] "
            f"the {law.name} law allows (approach {approach:.4g} m/s, separation {separation:.4g} m/s); "
            f"the contact was not resolved (reduce sim.rtol or sim.max_step)")
