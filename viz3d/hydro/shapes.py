"""Wall-motion shapes phi(y) on the wetted dam face 0 <= y <= h, and their modal moments.

Everything the series of ``viz3d.hydro.reservoir`` needs from a shape is its moment against the
reservoir's depth functions ``Y(y) = sin(mu (h - y))`` (mu real for a rigid bottom, complex for an
absorbing one),

    I(mu) = int_0^h phi(y) sin(mu (h - y)) dy,

plus four numbers that fix how fast those moments decay (used to choose the number of series
terms): ``top = phi(h)``, ``bottom = phi(0)``, ``sup = max |phi|`` and ``slope_variation =
|phi'(0)| + total variation of phi'``. Integrating by parts twice,

    I(mu) = phi(h) / mu - phi(0) cos(mu h) / mu - (1 / mu^2) int_0^h phi''(y) ... ,

and for a rigid bottom (cos(lambda_n h) = 0) ``|I_n - phi(h) / lambda_n| <= slope_variation /
lambda_n^2`` (docs/hydro.md, section "Moments").

Two representations share that interface:

* ``SampledShapes``: values at points y_0 = 0 < ... < y_M = h, meaning their piecewise-linear
  interpolant, whose moments have the exact closed form (summation by parts over the kinks)

      I = phi(h)/mu - phi(0) cos(mu h)/mu - [s_0 sin(mu h) + sum_k (s_k - s_{k-1}) sin(mu (h - y_k))] / mu^2,

  s_k the slope on [y_k, y_k+1]. Right for measured or tabulated shapes, kinks included.
* ``SmoothShapes``: a callable, integrated by composite Gauss-Legendre quadrature with panels of at
  most half a wavelength of the fastest depth function (exact to round-off for smooth phi).

Both hold ``n_shapes`` shapes at once; moments come out with a trailing axis of that length.
Units: phi in whatever units the caller's coordinates give (a dimensionless shape for a unit wall
acceleration; 1/sqrt(kg) for mass-normalised modes); y and h in metres.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from viz3d._typing import FloatArray

#: Gauss-Legendre points per quadrature panel of ``SmoothShapes``.
QUAD_POINTS = 12
#: Panel phase: each panel spans at most this phase of the fastest depth function sin(mu (h - y)).
#: Gauss-Legendre's remainder with n = QUAD_POINTS points on a panel of phase theta is about
#: theta^(2n+1) (n!)^4 / ((2n+1) ((2n)!)^3) relative: 2e-26 at theta = pi.
PANEL_PHASE = np.pi
#: At least this many panels, so that the shape itself is resolved whatever the depth functions.
MIN_PANELS = 32
#: Uniform samples from which a callable's decay constants (top, sup, slope variation) are read.
BOUND_SAMPLES = 4097
#: Points closer than this (relative to h) to 0 or h count as the ends of the face.
Y_RTOL = 1e-12
#: Remainder of the Taylor series of ``SmoothShapes.moments_near``, relative to int |phi| dy:
#: terms are added until x^(M+1) / (M+1)! e^x <= TAYLOR_RTOL, x = max |delta| h.
TAYLOR_RTOL = 1e-16
#: ``moments_near`` treats the terms in groups n < 8, 8 <= n < 32, ... (delta_n shrinks like 1/n, so
#: later groups need fewer Taylor terms).
TAYLOR_GROUP_START, TAYLOR_GROUP_GROWTH = 8, 4
#: Elements per block when moments are accumulated blockwise (keeps temporaries near 64 MB).
BLOCK_ELEMENTS = 1 << 22


def _as_columns(values, n_points: int) -> FloatArray:
    """Values (m,) or (m, k) as a float array (m, k)."""
    v = np.asarray(values, dtype=float)
    if v.ndim == 1:
        v = v[:, None]
    if v.ndim != 2 or v.shape[0] != n_points:
        raise ValueError(f"shape values must have shape ({n_points},) or ({n_points}, k), got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError("shape values must be finite")
    return v


def slope_variation(y: FloatArray, values: FloatArray) -> FloatArray:
    """|phi'(0)| + total variation of phi' of the piecewise-linear interpolant, per column (k,) [phi/m]."""
    slopes = np.diff(values, axis=0) / np.diff(y)[:, None]
    return np.abs(slopes[0]) + np.abs(np.diff(slopes, axis=0)).sum(axis=0)


def _blocks(n_rows: int, row_elements: int):
    """Slices of ``range(n_rows)`` whose blocks hold about BLOCK_ELEMENTS elements."""
    step = max(1, BLOCK_ELEMENTS // max(1, row_elements))
    for start in range(0, n_rows, step):
        yield slice(start, min(n_rows, start + step))


def _sin_depth_moments(mu: FloatArray, points: FloatArray, weights: FloatArray, depth: float) -> FloatArray:
    """sum_q sin(mu (h - points_q)) weights_q, blockwise: mu (...,), weights (q, k) -> (..., k)."""
    flat = np.ravel(mu)
    dtype = complex if np.iscomplexobj(flat) else float
    out = np.empty((flat.size, weights.shape[1]), dtype=dtype)
    arm = depth - points
    for rows in _blocks(flat.size, points.size):
        out[rows] = np.sin(flat[rows, None] * arm[None, :]) @ weights
    return out.reshape(np.shape(mu) + (weights.shape[1],))


@dataclass(frozen=True)
class SampledShapes:
    """Shapes given by samples, meaning their piecewise-linear interpolant on [0, h].

    Attributes
    ----------
    y : ndarray, shape (m,)
        Strictly increasing heights above the reservoir bottom [m], y[0] = 0, y[-1] = h.
    values : ndarray, shape (m, k)
        phi_j(y_i), one column per shape.
    """

    y: FloatArray
    values: FloatArray = field(repr=False)

    def __post_init__(self):
        y = np.asarray(self.y, dtype=float)
        if y.ndim != 1 or y.size < 2 or not np.all(np.diff(y) > 0):
            raise ValueError("sample heights y must be a strictly increasing 1-D array of at least 2 points")
        if abs(y[0]) > Y_RTOL * y[-1]:
            raise ValueError(f"samples must start at the reservoir bottom y = 0, got y[0] = {y[0]} m")
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "values", _as_columns(self.values, y.size))

    @property
    def depth(self) -> float:
        """h [m]: the highest sample is the free surface."""
        return float(self.y[-1])

    @property
    def n_shapes(self) -> int:
        return self.values.shape[1]

    @property
    def top(self) -> FloatArray:
        """phi(h), shape (k,)."""
        return self.values[-1]

    @property
    def bottom(self) -> FloatArray:
        """phi(0), shape (k,)."""
        return self.values[0]

    @property
    def sup(self) -> FloatArray:
        """max |phi| on [0, h], shape (k,)."""
        return np.abs(self.values).max(axis=0)

    @property
    def slope_variation(self) -> FloatArray:
        """|phi'(0)| + total variation of phi', shape (k,) [phi/m] (exact for the interpolant)."""
        return slope_variation(self.y, self.values)

    def __call__(self, y) -> FloatArray:
        """The interpolant at heights ``y`` (p,): shape (p, k)."""
        y = np.asarray(y, dtype=float)
        return np.stack([np.interp(y, self.y, v) for v in self.values.T], axis=-1)

    def moments(self, mu) -> FloatArray:
        """I(mu) = int_0^h phi sin(mu (h - y)) dy of the interpolant, exactly: mu (...,) -> (..., k)."""
        mu = np.asarray(mu)
        h = self.depth
        slopes = np.diff(self.values, axis=0) / np.diff(self.y)[:, None]
        kinks = np.diff(slopes, axis=0)
        m = mu[..., None]
        edge = (self.top - self.bottom * np.cos(m * h)) / m - slopes[0] * np.sin(m * h) / m**2
        if kinks.shape[0] == 0:
            return edge
        return edge - _sin_depth_moments(mu, self.y[1:-1], kinks, h) / m**2

    def moments_near(self, lam: FloatArray, delta: np.ndarray) -> np.ndarray:
        """I(lam_n + delta_wn): lam (N,), delta (w, N) -> (w, N, k); exact, as ``moments``."""
        return self.moments(lam[None, :] + delta)


@dataclass(frozen=True)
class SmoothShapes:
    """Shapes given by a smooth callable ``function(y) -> (p, k)`` on [0, depth].

    Moments come from composite Gauss-Legendre quadrature (``QUAD_POINTS`` per panel, panels at
    most half a wavelength of the fastest depth function and at least ``min_panels``): exact to
    round-off for shapes analytic on [0, h]. A shape with kinks or jumps should be passed as
    samples (``SampledShapes``) instead.

    Attributes
    ----------
    function : callable
        Maps heights (p,) [m] to values (p, k) (or (p,) for one shape).
    depth : float
        h [m].
    n_shapes : int
        k.
    min_panels : int
        Least number of quadrature panels (raise it for shapes with many oscillations).
    """

    function: Callable = field(repr=False)
    depth: float
    n_shapes: int
    min_panels: int = MIN_PANELS

    def __post_init__(self):
        if not self.depth > 0:
            raise ValueError(f"depth must be positive, got {self.depth}")
        probe = self(np.array([0.0, self.depth]))
        if probe.shape != (2, self.n_shapes):
            raise ValueError(f"function must map (p,) heights to (p, {self.n_shapes}) values, got {probe.shape}")

    @classmethod
    def from_function(cls, function: Callable, depth: float, min_panels: int = MIN_PANELS) -> SmoothShapes:
        """Wrap ``function`` and read the number of shapes from one evaluation."""
        probe = np.asarray(function(np.array([0.0, depth])), dtype=float)
        n_shapes = 1 if probe.ndim == 1 else probe.shape[1]
        return cls(function, float(depth), n_shapes, min_panels)

    def __call__(self, y) -> FloatArray:
        """Values at heights ``y`` (p,): shape (p, k)."""
        y = np.asarray(y, dtype=float)
        return _as_columns(self.function(y), y.size)

    def _samples(self) -> tuple[FloatArray, FloatArray]:
        y = np.linspace(0.0, self.depth, BOUND_SAMPLES)
        return y, self(y)

    @property
    def top(self) -> FloatArray:
        """phi(h), shape (k,)."""
        return self(np.array([self.depth]))[0]

    @property
    def bottom(self) -> FloatArray:
        """phi(0), shape (k,)."""
        return self(np.array([0.0]))[0]

    @property
    def sup(self) -> FloatArray:
        """max |phi| over BOUND_SAMPLES uniform samples, shape (k,)."""
        return np.abs(self._samples()[1]).max(axis=0)

    @property
    def slope_variation(self) -> FloatArray:
        """|phi'(0)| + total variation of phi', estimated from BOUND_SAMPLES samples, shape (k,) [phi/m]."""
        return slope_variation(*self._samples())

    def quadrature(self, mu_max: float) -> tuple[FloatArray, FloatArray]:
        """Gauss-Legendre points (q,) and weights (q,) on [0, h] for depth functions up to |mu| = mu_max."""
        n_panels = max(self.min_panels, int(np.ceil(mu_max * self.depth / PANEL_PHASE)))
        xi, wi = np.polynomial.legendre.leggauss(QUAD_POINTS)
        edges = np.linspace(0.0, self.depth, n_panels + 1)
        half = 0.5 * np.diff(edges)
        mid = 0.5 * (edges[1:] + edges[:-1])
        return (mid[:, None] + half[:, None] * xi).ravel(), (half[:, None] * wi).ravel()

    def moments(self, mu) -> FloatArray:
        """I(mu) = int_0^h phi sin(mu (h - y)) dy by quadrature: mu (...,) -> (..., k)."""
        mu = np.asarray(mu)
        points, weights = self.quadrature(float(np.abs(mu).max()) if mu.size else 0.0)
        return _sin_depth_moments(mu, points, weights[:, None] * self(points), self.depth)

    def moments_near(self, lam: FloatArray, delta: np.ndarray) -> np.ndarray:
        """I(lam_n + delta_wn) by Taylor's series in delta about the real lam_n: lam (N,), delta (w, N) -> (w, N, k).

        With s = h - y, ``sin((lam + delta) s) = sum_m (delta s)^m / m! sin(lam s + m pi / 2)``, so
        ``I = sum_m (delta h)^m / m! T_mn``, ``T_mn = int phi (s/h)^m sin(lam_n s + m pi/2) dy``: the T are
        real and frequency independent (one quadrature for all frequencies), the sum is Horner's rule.
        An absorbing bottom's eigenvalues are such lam_n + delta_wn with |delta_n| h = O(omega q h / n).
        """
        lam, delta = np.asarray(lam, float), np.asarray(delta)
        h = self.depth
        points, weights = self.quadrature(float(np.max(lam) + np.abs(delta).max()))
        s = h - points
        phi_w = weights[:, None] * self(points)  # (q, k)
        out = np.empty(delta.shape + (self.n_shapes,), dtype=complex)
        for group in _taylor_groups(lam.size):
            x = float(np.abs(delta[:, group]).max(initial=0.0)) * h
            order = _taylor_order(x)
            powers = (s / h)[:, None, None] ** np.arange(order + 1)[None, :, None] * phi_w[:, None, :]  # (q, M+1, k)
            T = _taylor_coefficients(lam[group], s, powers)
            dh = (delta[:, group] * h)[..., None]
            acc = T[order] + 0j * dh
            for m in range(order - 1, -1, -1):
                acc = T[m] + dh / (m + 1) * acc
            out[:, group] = acc
        return out


def _taylor_coefficients(lam: FloatArray, s: FloatArray, powers: FloatArray) -> FloatArray:
    """T_m = sum_q sin(lam s_q + m pi/2) powers[q, m]: lam (N,), s (q,), powers (q, M+1, k) -> (M+1, N, k), blockwise."""
    n_orders = powers.shape[1]
    T = np.empty((n_orders, lam.size, powers.shape[2]))
    sign = 1.0 - 2.0 * ((np.arange(n_orders) // 2) % 2)  # sin, cos, -sin, -cos, ...
    for rows in _blocks(lam.size, s.size):
        arg = np.outer(lam[rows], s)
        trig = (np.sin(arg), np.cos(arg))
        for m in range(n_orders):
            T[m, rows] = sign[m] * (trig[m % 2] @ powers[:, m, :])
    return T


def _taylor_groups(n_terms: int):
    """Slices n < 8, 8 <= n < 32, 32 <= n < 128, ... covering range(n_terms)."""
    start, stop = 0, TAYLOR_GROUP_START
    while start < n_terms:
        yield slice(start, min(stop, n_terms))
        start, stop = stop, stop * TAYLOR_GROUP_GROWTH


def _taylor_order(x: float) -> int:
    """Smallest M with x^(M+1) / (M+1)! e^x <= TAYLOR_RTOL: the Taylor remainder bound for |delta s| <= x."""
    order, term = 0, x * np.exp(x)
    while term > TAYLOR_RTOL:
        order += 1
        term *= x / (order + 1)
    return order


WallShapes = SampledShapes | SmoothShapes


def uniform(depth: float) -> SampledShapes:
    """phi = 1 on [0, depth]: a rigid wall moving as a whole (the seed's example, Westergaard's case)."""
    return SampledShapes(np.array([0.0, depth]), np.ones(2))


def as_shapes(shape, depth: float) -> WallShapes:
    """Coerce ``shape`` to wall shapes on [0, depth].

    Accepted: ``SampledShapes`` / ``SmoothShapes`` (their depth must equal ``depth``); a pair
    ``(y, values)`` of samples; a callable ``phi(y)`` returning (p,) or (p, k); a list of callables
    (one shape each) or of ``SampledShapes`` on the same heights.
    """
    if isinstance(shape, list):
        out = _stack(shape, depth)
    elif isinstance(shape, SampledShapes | SmoothShapes):
        out = shape
    elif callable(shape):
        out = SmoothShapes.from_function(shape, depth)
    elif isinstance(shape, tuple) and len(shape) == 2:
        out = SampledShapes(*shape)
    else:
        raise TypeError(f"a wall shape is a callable phi(y), a (y, values) pair or a shapes object, got {type(shape)}")
    if abs(out.depth - depth) > Y_RTOL * depth:
        raise ValueError(f"the shape covers [0, {out.depth}] m but the reservoir is {depth} m deep")
    return out


def _stack(shapes: list, depth: float) -> WallShapes:
    """One shapes object from a list: samples on common heights stay exact, callables become smooth."""
    if shapes and all(isinstance(s, SampledShapes) for s in shapes):
        if any(s.y.shape != shapes[0].y.shape or np.any(s.y != shapes[0].y) for s in shapes):
            raise ValueError("a list of sampled shapes must share its sample heights")
        return SampledShapes(shapes[0].y, np.column_stack([s.values for s in shapes]))
    if shapes and all(callable(s) and not isinstance(s, SampledShapes) for s in shapes):
        return SmoothShapes.from_function(lambda y: np.column_stack([np.asarray(s(y), float).reshape(len(y), -1)
                                                                     for s in shapes]), depth)
    raise TypeError("a list of shapes holds callables or SampledShapes on common heights, not a mix")
