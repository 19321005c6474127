"""Independent reference for the rigid mass on a bar: the characteristic grid ("method of steps").

Not the closed-form recursion of ``viz3d.contact.exact``: time is cut into ``n`` equal steps per
``T``, every wave is replaced by its step average (the round trip is exactly ``n`` steps, so the
delay is exact), the impactor equation ``V' = -k (V + 2 S)`` is integrated exactly over each step
with the step-average incoming wave ``S``, separation is detected at step starts and recontact at
the sub-step instant the gap closes. Event times converge like ``1/n``, velocities like ``1/n^2``.
Normalized units: time in ``T = 2L/c``, velocity in ``v``, stress in ``sqrt(E rho) v``.
"""

import math

import numpy as np


def grid_impact(beta: float, n: int, t_end: float, reflection: float = 1.0):
    """Return ``(events, final_velocity)``; events are ``(kind, time, impactor velocity)`` tuples."""
    k, h = 2.0 * beta, 1.0 / n
    out = np.zeros(int(t_end * n))
    V, gap, contact, events = 1.0, 0.0, True, []
    for i in range(out.size):
        S = reflection * out[i - n] if i >= n else 0.0
        if contact and V + 2.0 * S < 0.0:
            contact = False
            events.append(("separation", i * h, V))
        if contact:
            out[i], V = _contact_step(V, S, k, h)
            continue
        closing = V + 2.0 * S  # gap rate: impactor velocity minus end velocity (-2 S)
        if closing > 0.0 and gap + closing * h >= 0.0:
            f = -gap / closing
            avg, V = _contact_step(V, S, k, h - f)
            out[i] = (f * (-S) + (h - f) * avg) / h
            events.append(("contact", i * h + f, V))
            contact, gap = True, 0.0
        else:
            out[i], gap = -S, gap + closing * h
    return events, V


def _contact_step(V, S, k, dt):
    """Step average of the outgoing wave and the impactor velocity after ``dt`` in contact."""
    if dt <= 0.0:
        return 0.0, V
    decay = math.exp(-k * dt)
    return -S + (V + 2.0 * S) * (1.0 - decay) / (k * dt), -2.0 * S + (V + 2.0 * S) * decay
