"""Contacts as the physics defines them, from the contact intervals an integrator located.

A model resolves nothing shorter than its time resolution ``tau`` (for a truncated modal body,
the period of its highest retained mode, ``T/N`` for a bar of N axial modes): a kinematic
contact on such a body opens and closes within ``tau`` where the exact solution stays closed
(Gibbs ringing of the truncated series at the force jumps). ``physical_contacts`` therefore

* closes every gap shorter than ``tau`` (an *unresolved break*: the intervals it separates are
  one contact), and
* sets apart every recontact that, so merged, still lasts less than ``tau`` (an *unresolved
  touch*: the ringing contact point met the other body for less than one period of the highest
  mode; the model cannot say whether the bodies touched). The first contact of an impact is
  forced by the bodies' rigid approach and is a contact however short (a one-mode bar's contact
  lasts half its only period).

``impacts`` groups contacts into impacts: a new impact starts only when, between two contacts,
the loads have turned the bodies' rigid relative motion from separating to approaching; contacts
brought about by vibration (the bar end catching up with a receding impactor) belong to the
impact that set the vibration going.

Rows of contacts are ``(t_start, approach speed, t_end, separation speed)`` [s, m/s, s, m/s]
(``t_end`` and the separation speed nan for a contact still going on).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray


@dataclass(frozen=True)
class PhysicalContacts:
    """Contacts at a model's time resolution.

    Attributes
    ----------
    rows : ndarray, shape (k, 4)
        The resolved contacts: start [s], approach speed at it [m/s], end [s], separation speed at
        it [m/s].
    members : tuple of tuple of int, length k
        Indices of the located intervals each resolved contact is made of.
    breaks : ndarray of int, shape (k,)
        Unresolved breaks (gaps shorter than the resolution) closed inside each contact.
    touches : ndarray, shape (u, 4)
        Unresolved touches: merged contacts shorter than the resolution, set apart.
    touch_breaks : int
        Unresolved breaks closed inside the touches.
    resolution : float
        The time resolution used [s].
    """

    rows: FloatArray
    members: tuple[tuple[int, ...], ...]
    breaks: np.ndarray
    touches: FloatArray
    touch_breaks: int
    resolution: float

    @property
    def count(self) -> int:
        return len(self.rows)

    @property
    def unresolved_breaks(self) -> int:
        """Every gap shorter than the resolution, inside contacts and touches."""
        return int(self.breaks.sum()) + self.touch_breaks


def physical_contacts(intervals, resolution: float, opens_impact=None) -> PhysicalContacts:
    """Merge located contact intervals (m, 4) at ``resolution`` [s] (0: every interval is a contact).

    Gaps shorter than ``resolution`` are closed (the merged contact keeps the first approach and
    the last separation speed); merged contacts shorter than ``resolution`` are unresolved
    touches unless one of their intervals opens an impact (``opens_impact``, (m,) bool; default:
    the first interval only). An unfinished last contact (nan end) is never a touch.
    """
    c = np.asarray(intervals, float).reshape(-1, 4)
    opens = np.arange(len(c)) == 0 if opens_impact is None else np.asarray(opens_impact, bool)
    groups: list[list[int]] = []
    for i, (start, _, _, _) in enumerate(c):
        if groups and start - _end(c[groups[-1][-1]]) < resolution:
            groups[-1].append(i)
        else:
            groups.append([i])
    merged = np.array([[c[g[0], 0], c[g[0], 1], c[g[-1], 2], c[g[-1], 3]] for g in groups]).reshape(-1, 4)
    short = merged[:, 2] - merged[:, 0] < resolution  # nan end: False, a contact still going on
    short &= np.array([not opens[g].any() for g in groups], bool).reshape(-1)
    breaks = np.array([len(g) - 1 for g in groups], int)
    return PhysicalContacts(merged[~short], tuple(tuple(g) for g, s in zip(groups, short) if not s),
                            breaks[~short], merged[short], int(breaks[short].sum()), float(resolution))


def _end(row) -> float:
    return row[0] if np.isnan(row[2]) else row[2]


def impacts(rigid_onset: FloatArray, rigid_end: FloatArray) -> list[list[int]]:
    """Indices of the contacts of each impact.

    Parameters
    ----------
    rigid_onset, rigid_end : ndarray, shape (k,)
        Rigid relative normal velocity of the bodies (approaching > 0) just before each contact
        starts and when it ends [m/s] (nan for an unfinished contact).

    A contact starts a new impact when the previous contact ended with the rigid motions
    separating (<= 0) and it starts with them approaching (> 0): only the loads can have turned
    them round in between.
    """
    groups: list[list[int]] = []
    for i, v_on in enumerate(np.asarray(rigid_onset, float)):
        turned = i > 0 and rigid_end[i - 1] <= 0.0 < v_on
        if not groups or turned:
            groups.append([i])
        else:
            groups[-1].append(i)
    return groups
