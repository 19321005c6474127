"""What a run's contacts amounted to: contacts as the physics defines them, impacts, the bodies'
restitution, and what the model cannot resolve (the trajectory's contact fields, docs/trajectory.md).

Per contact (a ``[[contacts]]`` entry), the located touches (``viz3d.events.ContactRecord``) are
merged at the contact's time resolution (``viz3d.contact.intervals.physical_contacts``): for a
kinematic contact on a truncated modal body, the period of the highest retained mode (Gibbs
ringing); 0 otherwise (a law contact is resolved at its own time scale by the step bound,
restitution impulses are instants). Impacts group the touches of one contact
(``viz3d.contact.intervals.impacts``); the bodies' restitution of an impact is ``-v_after /
v_before`` of the relative normal velocity of their centres of mass, before its first touch and
after its last. Instantaneous impulses of a kinematic contact on a flexible body are shorter than
the model's resolution: their sum, times the rigid mobility, is the stated uncertainty.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from viz3d._typing import FloatArray
from viz3d.contact.intervals import impacts, physical_contacts


@dataclass(frozen=True)
class ContactReport:
    """Contacts, impacts and restitution of a run.

    Attributes
    ----------
    names : ndarray of str, shape (k,)
        Contact of each resolved touch.
    rows : ndarray, shape (k, 4)
        Resolved touches: start [s], approach speed [m/s], end [s], separation speed [m/s], by start time.
    breaks : ndarray of int, shape (k,)
        Unresolved breaks closed inside each.
    touches : ndarray, shape (u, 4)
        Unresolved touches set apart.
    events : ndarray, shape (m, 4)
        Every located touch, as rows.
    restitution : ndarray, shape (ni,)
        The bodies' restitution of every impact, in time order.
    speeds : ndarray, shape (ni, 2)
        Relative normal velocity of the centres of mass before and after each impact [m/s].
    uncertainty : ndarray, shape (ni,)
        What the model cannot resolve in each restitution (see the module docstring).
    velocity_uncertainty : float
        The same for body 1's final velocity [m/s].
    relative_velocity_uncertainty : float
        The same for the final relative normal velocity of the bodies' centres of mass [m/s].
    resolution : float
        The largest time resolution used [s].
    """

    names: np.ndarray
    rows: FloatArray
    breaks: np.ndarray
    touches: FloatArray
    events: FloatArray
    restitution: FloatArray
    speeds: FloatArray
    uncertainty: FloatArray
    velocity_uncertainty: float
    relative_velocity_uncertainty: float
    resolution: float
    impact_contacts: list = field(default_factory=list)

    @property
    def count(self) -> int:
        return len(self.rows)


def contact_report(records, impulses, rigid_now: dict[str, float], resolutions: dict[str, float],
                   mobilities: dict[str, tuple[float, float]]) -> ContactReport:
    """The report of a run.

    Parameters
    ----------
    records : list of ContactRecord
        Every located touch (``viz3d.events.ContactStepping.records``).
    impulses : list of (float, str, float)
        Time, contact and impulse [N s] of every impulse.
    rigid_now : dict
        Per contact, the relative normal velocity of its bodies' centres of mass at the end [m/s].
    resolutions : dict
        Per contact, its time resolution [s].
    mobilities : dict
        Per contact, ``(1 / m_1, 1 / m_1 + 1 / m_2)`` of its bodies' rigid motion [1/kg] (for the
        uncertainty), 0 when no impulse is unresolved.
    """
    names, rows, breaks, touches, events = [], [], [], [], []
    rest, speeds, unc, groups_all = [], [], [], []
    v_unc, v_rel_unc = 0.0, 0.0
    for name in dict.fromkeys(r.contact for r in records):
        mine = [r for r in records if r.contact == name]
        located = np.array([[r.t_start, r.approach, r.t_end, r.separation] for r in mine], float)
        rigid = np.array([[r.rigid_start, r.rigid_end] for r in mine], float)
        groups = impacts(rigid[:, 0], rigid[:, 1])
        opens = np.isin(np.arange(len(mine)), [g[0] for g in groups])
        phys = physical_contacts(located, resolutions.get(name, 0.0), opens)
        names += [name] * len(phys.rows)
        rows.append(phys.rows)
        breaks.append(phys.breaks)
        touches.append(phys.touches)
        events.append(located)
        P = np.array([abs(p) for t, c, p in impulses if c == name]) if mobilities.get(name, (0, 0))[1] else np.zeros(0)
        t_P = np.array([t for t, c, p in impulses if c == name])[: len(P)]
        owner = np.searchsorted(located[:, 0], t_P, side="right") - 1
        for g in groups:
            after = rigid_now[name] if np.isnan(rigid[g[-1], 1]) else rigid[g[-1], 1]
            before = rigid[g[0], 0]
            speeds.append([before, after])
            with np.errstate(divide="ignore", invalid="ignore"):
                rest.append(-after / before)
                unc.append(mobilities.get(name, (0.0, 0.0))[1] * P[np.isin(owner, g)].sum() / abs(before))
            groups_all.append((name, g))
        v_unc += mobilities.get(name, (0.0, 0.0))[0] * float(P.sum())
        v_rel_unc += mobilities.get(name, (0.0, 0.0))[1] * float(P.sum())
    rows_all = np.concatenate(rows) if rows else np.zeros((0, 4))
    order = np.argsort(rows_all[:, 0], kind="stable")
    first = np.argsort([t for t, in _starts(groups_all, records)], kind="stable").astype(int)
    return ContactReport(np.array(names, dtype=str)[order], rows_all[order],
                         (np.concatenate(breaks) if breaks else np.zeros(0, int))[order],
                         np.concatenate(touches) if touches else np.zeros((0, 4)),
                         np.concatenate(events) if events else np.zeros((0, 4)),
                         np.array(rest, float)[first], np.array(speeds, float).reshape(-1, 2)[first],
                         np.array(unc, float)[first], v_unc, v_rel_unc, max(resolutions.values(), default=0.0), groups_all)


def _starts(groups_all, records) -> list[tuple[float]]:
    """Start time of each impact (its first touch), to order impacts of several contacts in time."""
    out = []
    for name, g in groups_all:
        mine = [r for r in records if r.contact == name]
        out.append((mine[g[0]].t_start,))
    return out


def per_contact_restitution(rows: FloatArray) -> FloatArray:
    """Separation over approach speed of the contact points, per resolved touch (nan if unfinished)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return rows[:, 3] / rows[:, 1] if len(rows) else np.zeros(0)
