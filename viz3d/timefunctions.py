"""Time functions for applied loads, evaluated for many loads at once.

Every load value is ``offset + amplitude * shape(t)`` with one scalar shape per load, chosen by
name in the scene (``kind``):

==========  ===================================================================
constant    ``0`` (the value is ``offset``)
sine        ``sin(2 pi frequency t + phase)``
step        ``1`` for ``t >= start``, else ``0``
ramp        ``0`` before ``start``, linear to ``1`` over ``duration``, then ``1``
pulse       ``1`` for ``start <= t < start + duration``, else ``0``
smooth_ramp ``0`` before ``start``, ``tau / T - sin(2 pi tau / T) / (2 pi)`` over ``T = duration``
            (``tau = t - start``), then ``1``: a cycloidal ramp, its rate and acceleration
            continuous (Kane, Ryan & Banerjee's spin-up as a velocity profile)
==========  ===================================================================

A scene never executes code; these six shapes are the whole vocabulary.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray
from viz3d.compiled import jit

TIME_FUNCTIONS = ("constant", "sine", "step", "ramp", "pulse", "smooth_ramp")


@dataclass(frozen=True)
class TimeFunctions:
    """``k`` vector-valued time functions.

    Attributes
    ----------
    kind : ndarray of int, shape (k,)
        Index into ``TIME_FUNCTIONS``.
    offset, amplitude : ndarray, shape (k, 3)
        Value units (N or N m).
    frequency : ndarray, shape (k,)
        [Hz] (sine).
    phase : ndarray, shape (k,)
        [rad] (sine).
    start, duration : ndarray, shape (k,)
        [s] (step, ramp, pulse).
    """

    kind: np.ndarray
    offset: FloatArray
    amplitude: FloatArray
    frequency: FloatArray
    phase: FloatArray
    start: FloatArray
    duration: FloatArray

    @classmethod
    def from_entries(cls, entries: list[dict]) -> "TimeFunctions":
        """Build from resolved scene entries (each with the keys named in the class docstring)."""

        def col(key, shape=()):
            return np.array([e[key] for e in entries], dtype=float).reshape((len(entries),) + shape)

        kind = np.array([TIME_FUNCTIONS.index(e["kind"]) for e in entries], dtype=int)
        return cls(kind, col("offset", (3,)), col("amplitude", (3,)), col("frequency"), col("phase"),
                   col("start"), col("duration"))

    def shape(self, t: float) -> FloatArray:
        """Scalar shape of each function at time ``t`` [s], shape (k,)."""
        tau = t - self.start
        ramp = np.clip(tau / np.where(self.duration > 0, self.duration, 1.0), 0.0, 1.0)
        ramp = np.where(self.duration > 0, ramp, (tau >= 0).astype(float))
        table = np.stack([
            np.zeros_like(tau),
            np.sin(2 * np.pi * self.frequency * t + self.phase),
            (tau >= 0).astype(float),
            ramp,
            ((tau >= 0) & (tau < self.duration)).astype(float),
            np.where(self.duration > 0, ramp - np.sin(2 * np.pi * ramp) / (2 * np.pi), ramp),
        ])
        return np.take_along_axis(table, self.kind[None], axis=0)[0]

    def __call__(self, t: float) -> FloatArray:
        """Values at time ``t`` [s], shape (k, 3)."""
        return self.offset + self.amplitude * self.shape(t)[:, None]

    def table(self) -> tuple[np.ndarray, FloatArray]:
        """Packed for the compiled ``value``: kinds (k,) and rows (k, 10) ``[offset (3), amplitude (3),
        frequency, phase, start, duration]``."""
        rows = np.column_stack([self.offset, self.amplitude, self.frequency, self.phase, self.start, self.duration])
        return self.kind.astype(np.int64), rows.reshape(-1, 10)


@jit
def value(kind, f, t, out):
    """Compiled ``TimeFunctions.__call__`` of one function: ``out = offset + amplitude shape(t)`` (3,)
    from its kind and packed row ``f`` (10,) (``TimeFunctions.table``)."""
    tau = t - f[8]
    if kind == 1:
        shape = math.sin(2.0 * math.pi * f[6] * t + f[7])
    elif kind == 2:
        shape = 1.0 if tau >= 0.0 else 0.0
    elif kind == 3:
        if f[9] > 0.0:
            shape = min(max(tau / f[9], 0.0), 1.0)
        else:
            shape = 1.0 if tau >= 0.0 else 0.0
    elif kind == 4:
        shape = 1.0 if (tau >= 0.0 and tau < f[9]) else 0.0
    elif kind == 5:
        shape = min(max(tau / f[9], 0.0), 1.0) if f[9] > 0.0 else (1.0 if tau >= 0.0 else 0.0)
        shape -= math.sin(2.0 * math.pi * shape) / (2.0 * math.pi)
    else:
        shape = 0.0
    for c in range(3):
        out[c] = f[c] + f[3 + c] * shape


#: Profiles a drive may follow (``profile``): a prescribed position must have a bounded second
#: derivative (sine or constant); a prescribed velocity a bounded first derivative (ramp too).
PROFILE_KINDS = {"position": ("constant", "sine", "smooth_ramp"), "velocity": ("constant", "sine", "ramp", "smooth_ramp")}


@jit
def profile(kind, velocity, f, t):
    """``(r, r_dot, r_ddot)`` of a scalar profile at ``t`` [s] from the first component of a packed
    time function ``f`` (``TimeFunctions.table``: offset ``f[0]``, amplitude ``f[3]``): with
    ``velocity`` 0 the function is ``r``; with 1 it is ``r_dot`` and ``r`` its integral from
    ``t = 0`` (``r(0) = 0``). Kinds of ``PROFILE_KINDS`` only (others give zeros). Compiled code
    calls it; Python calls ``profile_value`` (the same function, uncompiled)."""
    a0, a1 = f[0], f[3]
    s = ds = dds = S = 0.0
    if kind == 1:  # sine
        w = 2.0 * math.pi * f[6]
        s, ds, dds = math.sin(w * t + f[7]), w * math.cos(w * t + f[7]), -w * w * math.sin(w * t + f[7])
        S = (math.cos(f[7]) - math.cos(w * t + f[7])) / w if w > 0.0 else t * math.sin(f[7])
    elif kind == 3 and f[9] > 0.0:  # ramp from f[8] over f[9]: S = I(t - start) - I(-start)
        T = f[9]
        for tau, sign in ((t - f[8], 1.0), (-f[8], -1.0)):
            if tau >= T:
                S += sign * (0.5 * T + (tau - T))
            elif tau > 0.0:
                S += sign * 0.5 * tau * tau / T
        tau = t - f[8]
        # on a corner (to the round-off of a stage time t_n + c h) the slope is the mean of its two
        # sides: RK4 evaluates a corner on a step boundary twice, as the last stage of one step and
        # the first of the next, with equal weights, so their errors cancel (any one side would
        # leave the prescribed velocity off by h * jump / 6 for good)
        near = 8.0 * 2.220446049250313e-16 * max(abs(t), abs(f[8]) + T)
        if abs(tau) <= near:
            ds = 0.5 / T
        elif abs(tau - T) <= near:
            s, ds = 1.0, 0.5 / T
        elif tau >= T:
            s = 1.0
        elif tau > 0.0:
            s, ds = tau / T, 1.0 / T
    elif kind == 5 and f[9] > 0.0:  # smooth ramp from f[8] over f[9]: S = I(t - start) - I(-start)
        T, a = f[9], 2.0 * math.pi / f[9]
        for tau, sign in ((t - f[8], 1.0), (-f[8], -1.0)):
            if tau >= T:
                S += sign * (tau - 0.5 * T)
            elif tau > 0.0:
                S += sign * (0.5 * tau * tau / T + (math.cos(a * tau) - 1.0) / (a * a * T))
        tau = t - f[8]
        if tau >= T:
            s = 1.0
        elif tau > 0.0:
            s, ds, dds = tau / T - math.sin(a * tau) / (2.0 * math.pi), (1.0 - math.cos(a * tau)) / T, a * math.sin(a * tau) / T
    if velocity == 1:
        return a0 * t + a1 * S, a0 + a1 * s, a1 * ds
    return a0 + a1 * s, a1 * ds, a1 * dds


#: ``profile`` for Python callers (numba's inner functions have no Python entry).
profile_value = getattr(profile, "py_func", profile)
