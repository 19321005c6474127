"""Compiled normal-force pieces (``viz3d.compiled.normal_force``) against the NumPy laws.

Every law of ``NORMAL_LAWS`` (its example instance, plus ``LinearPlastic`` with an explicit
``K_h2``) is evaluated both ways over random and edge-case inputs: no indentation, the virgin
curve, unloading between ``alpha_r`` and ``alpha_m``, below the crater, histories below and above
yield (and beyond the fully plastic indentation), both signs of the rate, memories from
``onset`` / ``update``.
"""

from dataclasses import dataclass, replace

import numba
import numpy as np
import pytest
from law_examples import EXAMPLES, K_HERTZ, M_EFF, V0

from viz3d.compiled import normal_force, registered
from viz3d.contact.laws import (
    MIN_APPROACH_SPEED,
    NORMAL_LAWS,
    ContactMemory,
    Hertz,
    HertzianUnloading,
    HysteresisLaw,
    Linear,
    PowerPlastic,
    YieldThenLinear,
    YigitChristoforou,
    YigitChristoforouItems,
)

EPS = np.finfo(float).eps
#: Tolerance factor on eps * (sum of |terms| + |dF/dalpha_r| alpha_m), from counting roundings.
#: Each operation rounds to eps/2 relative (+ - * / sqrt), a pow to at most 4 ulp (libm in numba, a
#: SIMD pow possibly in NumPy). To first order an error is the sum over the intermediate results of
#: |dF/dx| |x| times their relative rounding; force-level intermediates are bounded by the sum of
#: the terms' magnitudes, indentation-level ones (alpha - alpha_Y, alpha_r, alpha - alpha_r) by
#: alpha_m, which reaches F through the slope |dF/dalpha_r|. Longest chain, PowerPlastic unloading:
#: F_m ~6 eps; the interpolation ratio and a_m^2 ~6 eps, amplified 1.5x by ^1.5 plus one pow ~13;
#: R* = 4 E* (a_m^2)^1.5 / (3 F_m) ~22, halved by sqrt plus 2 products -> K_u ~13 eps;
#: (F_m / K_u)^(2/3) ~ 2/3 (6 + 13) + 4 ~17 eps of alpha_m - alpha_r, so alpha_r within ~17 eps
#: alpha_m; the final K_u (alpha - alpha_r)^1.5 adds ~18 eps of F. Each implementation is thus
#: within ~20 eps (terms + slope term) of the exact value, their difference within ~40: 64 keeps
#: a margin for the looseness of this count, and is far below any formula error (an alpha_r off by
#: a wrong exponent or branch changes F at order 1).
ROUNDING = 64
#: Junk columns prepended to test p0 > 0 (nan: a piece reading them returns nan).
JUNK = 3
#: Indentation scale of the non-plastic laws [m]: Hertz peak of the example impact,
#: (5 m v0^2 / (4 K))^(2/5) (the linear law's stiffness is the Hertz secant there).
HERTZ_PEAK = (5.0 * M_EFF * V0**2 / (4.0 * K_HERTZ)) ** 0.4
#: Depths of the stored alpha_m, in units of the law's scale (alpha_Y): none, elastic, exactly at
#: yield, just above, plastic, deep (thesis Fig. 7.4: "hundreds").
DEPTHS = (0.0, 0.3, 1.0, 1.0 + 1e-9, 1.5, 30.0, 300.0)
RNG_SEED = 20240

CASES = {name: EXAMPLES[name] for name in sorted(NORMAL_LAWS)}
CASES["linear_plastic_K_h2"] = replace(EXAMPLES["linear_plastic"], K_h2=1.8 * EXAMPLES["linear_plastic"].K_h)
#: The fixed-constants parametrisation (Hunt-Crossley steel on steel, c = 0.2664 s/m): no approach speed read.
CASES["hunt_crossley_fixed"] = replace(EXAMPLES["hunt_crossley"], damping_factor=0.2664)


@numba.njit
def _pieces(d, k, p0, alpha, alpha_dot, approach_speed, alpha_max):
    """``normal_force`` of contact ``k`` at each ``(alpha, alpha_dot)`` [N]."""
    out = np.empty(alpha.size)
    for j in range(alpha.size):
        out[j] = normal_force(d, k, p0, alpha[j], alpha_dot[j], approach_speed, alpha_max, True)
    return out


def _data(law, junk=0):
    """Packed data of the law, ``junk`` nan columns before its parameters; the law in row ``rows - 1``."""
    f = np.hstack([np.full((1, junk), np.nan), law.params()[None, :]])
    if junk:
        f = np.vstack([np.full_like(f, np.nan), f])  # a junk row before: k must be honoured too
    return law.compiled_items(np.zeros((f.shape[0], 0), np.int64), np.ascontiguousarray(f))


def _compiled(law, alpha, alpha_dot, memory, junk=0):
    d = _data(law, junk)
    alpha, alpha_dot = np.broadcast_arrays(np.asarray(alpha, float), np.asarray(alpha_dot, float))
    return _pieces(d, d.f.shape[0] - 1, junk, np.ascontiguousarray(alpha), np.ascontiguousarray(alpha_dot),
                   float(memory.approach_speed), float(memory.alpha_max))


def _scale(law):
    """Indentation scale [m]: ``alpha_Y`` of a plastic law, the Hertz peak otherwise."""
    return getattr(law, "alpha_Y", HERTZ_PEAK)


def _memories(law):
    """Memories given directly and built by ``onset`` / ``update`` (craters persist across onsets)."""
    scale = _scale(law)
    depths = [x * scale for x in DEPTHS]
    if isinstance(law, PowerPlastic):
        depths += [law.alpha_fp, 3.0 * law.alpha_fp]  # at and beyond the fully plastic indentation
    direct = [ContactMemory(V0, a, float(law.residual_indentation(a))) for a in depths]
    fresh = law.onset(V0)
    loaded = law.update(fresh, 2.0 * scale, V0)
    unloading = law.update(loaded, 1.2 * scale, -V0)
    again = law.onset(3.0 * V0, unloading)
    deeper = law.update(law.update(again, 40.0 * scale, 2.0 * V0), 10.0 * scale, -0.5 * V0)
    slow = law.onset(0.01 * MIN_APPROACH_SPEED, deeper)  # raised to MIN_APPROACH_SPEED
    return direct + [fresh, loaded, unloading, again, deeper, slow]


def _inputs(law, memory, rng):
    """Edge cases and random ``(alpha, alpha_dot)`` around the memory's ``alpha_m`` and ``alpha_r``."""
    scale = _scale(law)
    a_m = memory.alpha_max
    a_r = float(law.residual_indentation(a_m))
    top = 3.0 * a_m + 2.0 * scale
    edges = [-scale, -1e-12 * scale, -0.0, 0.0, 1e-12 * scale, scale, a_m, a_m * (1 - 1e-12), a_m * (1 + 1e-12),
             a_r, a_r * (1 - 1e-9), a_r * (1 + 1e-9), 0.5 * a_r, 0.5 * (a_r + a_m)]
    alpha = np.concatenate([edges, rng.uniform(a_r, a_m, 12), rng.uniform(0.0, a_r, 4),
                            rng.uniform(a_m, top, 8), rng.uniform(0.0, top, 8), rng.uniform(-scale, 0.0, 2)])
    alpha_dot = rng.uniform(-3.0, 3.0, alpha.size) * V0
    alpha_dot[::7] = 0.0
    return alpha, alpha_dot


def _terms(law, alpha, alpha_dot, memory):
    """Sum of the magnitudes of the force-level terms the law's formulas add or subtract [N]."""
    a = np.maximum(alpha, 0.0)
    if isinstance(law, Linear):
        return law.stiffness * a + np.abs(law.damping * alpha_dot)
    if isinstance(law, Hertz):
        return law.stiffness * a**law.exponent
    if isinstance(law, HysteresisLaw):
        return law.stiffness * a**law.exponent * (1.0 + np.abs(law.factor() * alpha_dot / memory.approach_speed))
    if not isinstance(law, YieldThenLinear | PowerPlastic):
        raise NotImplementedError(f"state the rounding bound of {type(law).__name__} here")
    a = np.maximum(np.maximum(a, memory.alpha_max), law.alpha_Y)  # every indentation the formulas see
    if isinstance(law, YieldThenLinear):
        plastic = law.F_Y + law.K_Y * a
    else:
        plastic = law.F_Y + law.K_hY * (a**law.n + law.alpha_Y**law.n)
    # Hertz branch, Yigit-Christoforou's K_h alpha_m^1.5 and K_h alpha^1.5, F_m on top of the
    # loading terms: each kind of term at most twice
    return 2.0 * (law.K_h * a**1.5 + plastic)


def _crater_sensitivity(law, alpha, memory):
    """``|dF/dalpha_r| alpha_m`` [N] on a Hertzian unloading branch (the only computed, subtracted
    indentation: an error of ``alpha_r`` ~ eps alpha_m shifts F by the slope), 0 elsewhere."""
    if not isinstance(law, HertzianUnloading):
        return np.zeros_like(alpha)
    a_m = memory.alpha_max
    slope = 1.5 * law.unloading_stiffness(a_m) * np.sqrt(np.maximum(alpha - law.residual_indentation(a_m), 0.0))
    return np.where((alpha > 0.0) & (alpha < a_m), slope * a_m, 0.0)


def _tolerance(law, alpha, alpha_dot, memory):
    return ROUNDING * EPS * (_terms(law, alpha, alpha_dot, memory) + _crater_sensitivity(law, alpha, memory))


@pytest.mark.parametrize("name", sorted(NORMAL_LAWS))
def test_every_law_has_a_registered_compiled_piece(name):
    cls = NORMAL_LAWS[name]
    assert cls.compiled_items is not None, f"{name}: no compiled piece (its contacts would run on NumPy)"
    assert cls.compiled_items in registered(normal_force)
    assert EXAMPLES[name].params().ndim == 1


@pytest.mark.parametrize("case", sorted(CASES))
def test_compiled_piece_reproduces_the_numpy_force(case):
    law = CASES[case]
    rng = np.random.default_rng(RNG_SEED)
    count = 0
    for memory in _memories(law):
        alpha, alpha_dot = _inputs(law, memory, rng)
        expected = law.force(alpha, alpha_dot, memory)
        got = _compiled(law, alpha, alpha_dot, memory)
        tol = _tolerance(law, alpha, alpha_dot, memory)
        bad = ~(np.abs(got - expected) <= tol)  # also catches nan
        assert not bad.any(), (f"{case}, {memory}: alpha {alpha[bad]}, alpha_dot {alpha_dot[bad]}: "
                               f"compiled {got[bad]}, NumPy {expected[bad]}, tolerance {tol[bad]}")
        assert np.all(got[alpha <= 0.0] == 0.0) and np.all(got >= 0.0)
        # p0 > 0 and k > 0: the same compiled code reads the same numbers, so the same bits
        np.testing.assert_array_equal(_compiled(law, alpha, alpha_dot, memory, junk=JUNK), got)
        count += alpha.size
    assert count >= 300


@pytest.mark.parametrize("name", sorted(NORMAL_LAWS))
@pytest.mark.parametrize("approach_speed", [0.0, -V0])
def test_piece_without_a_required_approach_speed_returns_nan(name, approach_speed):
    """Hysteresis laws need ``alpha_dot_0 > 0`` (NumPy raises): their piece gives nan, which the
    step's health check reports; laws that do not use it are unaffected."""
    law = EXAMPLES[name]
    memory = ContactMemory(approach_speed=approach_speed)
    alpha = np.array([0.5, 1.0, 2.0]) * _scale(law)
    alpha_dot = np.array([V0, 0.0, -V0])
    got = _compiled(law, alpha, alpha_dot, memory)
    if isinstance(law, HysteresisLaw):
        with pytest.raises(ValueError):
            law.force(alpha, alpha_dot, memory)
        assert np.all(np.isnan(got))
    else:
        expected = law.force(alpha, alpha_dot, memory)
        assert np.all(np.abs(got - expected) <= _tolerance(law, alpha, alpha_dot, memory))
    assert np.all(_compiled(law, np.array([-1.0, 0.0]) * _scale(law), np.array([V0, V0]), memory) == 0.0)


def test_a_subclass_with_other_formulas_loses_the_inherited_piece():
    @dataclass(frozen=True)
    class Renamed(YigitChristoforou):
        name = "renamed"

    @dataclass(frozen=True)
    class Stiffer(YigitChristoforou):
        def unloading_force(self, alpha, alpha_max):
            return 2.0 * super().unloading_force(alpha, alpha_max)

    assert Renamed.compiled_items is YigitChristoforouItems
    assert Stiffer.compiled_items is None
