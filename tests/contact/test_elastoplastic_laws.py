"""V15: elastoplastic contact laws of thesis sec. 7.3.3-7.3.5 (sphere R = 25 mm on a steel flat).

Formulas are re-typed here from the thesis (with the errata of digest Appendix A fixed) and compared
with the law classes; loop areas are integrated by quadrature of the force, independently of the
laws' closed-form energies.
"""

import numpy as np
import pytest
from law_examples import EXAMPLES, M_EFF, NU, SIGMA_Y, V0, E, R
from scipy.integrate import quad

from viz3d.contact.parameters import plane_strain_modulus
from viz3d.contact.single_impact import achieved_restitution

PLASTIC = ("yigit_christoforou", "linear_plastic", "power_plastic")
#: Closed forms vs their own re-typed formula: rounding only.
FORMULA_RTOL = 1e-12
#: quad on smooth branches (epsrel 1e-12 requested).
QUAD_RTOL = 1e-9
#: Relative steps used to probe continuity: a continuous force changes ~10x less over the second.
PROBES = (1e-6, 1e-7)
#: Loading depths probed, in units of alpha_Y: elastic, just plastic, deep (thesis Fig. 7.4: "hundreds").
DEPTHS = (0.5, 1.5, 30.0, 300.0)


def _loaded(law, alpha_m):
    """Memory after loading to ``alpha_m``."""
    return law.update(law.onset(V0), alpha_m, 0.0)


def _loaded_to_depth(name, depth):
    """The example law, ``alpha_m = depth alpha_Y``, the memory at onset and the one after loading to ``alpha_m``."""
    law = EXAMPLES[name]
    alpha_m = depth * law.alpha_Y
    return law, alpha_m, law.onset(V0), _loaded(law, alpha_m)


def _integral(f, a, b, points=None):
    """quad to 1e-12 relative, no absolute floor (the energies are ~1e-4..1 J)."""
    return quad(f, a, b, points=points, epsrel=1e-12, epsabs=0.0, limit=200)[0]


def _loop_works(law, fresh, mem, alpha_m):
    """Quadrature of the force: work of loading from 0 to ``alpha_m`` (memory ``fresh``) and energy
    given back unloading from ``alpha_m`` to the residual indentation (memory ``mem``)."""
    load = _integral(lambda a: law.force(a, V0, fresh), 0.0, alpha_m, points=[law.alpha_Y])
    unload = _integral(lambda a: law.force(a, -V0, mem), mem.alpha_residual, alpha_m)
    return load, unload


def _assert_continuous(force_near, value, label):
    """``force_near(h)`` -> value as h -> 0 linearly (a jump would not shrink with h)."""
    gaps = [abs(force_near(h) - value) for h in PROBES]
    assert gaps[1] <= 0.2 * gaps[0] or gaps[1] <= FORMULA_RTOL * abs(value), f"{label}: jump {gaps}"


@pytest.mark.parametrize("name", PLASTIC)
def test_force_is_continuous_at_yield(name):
    law = EXAMPLES[name]
    a = law.alpha_Y
    fresh = law.onset(V0)
    F_Y = law.K_h * a**1.5
    assert law.force(a, V0, fresh) == pytest.approx(F_Y, rel=FORMULA_RTOL, abs=0)
    _assert_continuous(lambda h: law.force(a * (1 + h), V0, fresh), F_Y, "above yield")
    _assert_continuous(lambda h: law.force(a * (1 - h), V0, fresh), F_Y, "below yield")


@pytest.mark.parametrize("name", PLASTIC)
@pytest.mark.parametrize("depth", DEPTHS)
def test_force_is_continuous_at_the_maximum_indentation(name, depth):
    """Unloading starts from the loading force at alpha_m; the memory update does not change the force."""
    law, alpha_m, before, after = _loaded_to_depth(name, depth)
    F_m = law.force(alpha_m, 0.0, before)
    assert law.force(alpha_m, 0.0, after) == pytest.approx(F_m, rel=FORMULA_RTOL, abs=0)
    _assert_continuous(lambda h: law.force(alpha_m * (1 - h), -V0, after), F_m, "unloading from alpha_m")
    assert law.force(after.alpha_residual, -V0, after) == pytest.approx(0.0, abs=FORMULA_RTOL * F_m)


def test_yigit_christoforou_formulas():
    """(7.6)-(7.10); residual indentation from F_de = 0 (the printed 7.12 is garbled)."""
    law = EXAMPLES["yigit_christoforou"]
    Ep = plane_strain_modulus(E, NU)
    assert law.K_h == pytest.approx(2.0 / 3.0 * Ep * np.sqrt(R), rel=FORMULA_RTOL, abs=0)
    assert law.alpha_Y == pytest.approx(2.72 * np.pi**2 * SIGMA_Y**2 * R / Ep**2, rel=FORMULA_RTOL, abs=0)
    K_Y = 1.5 * law.K_h * law.alpha_Y**0.5
    a_Y, a_m = law.alpha_Y, 30.0 * law.alpha_Y
    mem = _loaded(law, a_m)
    a_r = (a_m**1.5 - a_Y**1.5 - K_Y / law.K_h * (a_m - a_Y)) ** (2.0 / 3.0)
    assert mem.alpha_residual == pytest.approx(a_r, rel=FORMULA_RTOL, abs=0)
    alpha = 0.5 * (a_r + a_m)
    F_de = law.K_h * (alpha**1.5 - a_m**1.5 + a_Y**1.5) + K_Y * (a_m - a_Y)
    assert law.force(alpha, -V0, mem) == pytest.approx(F_de, rel=FORMULA_RTOL, abs=0)
    assert law.force(0.99 * a_r, -V0, mem) == 0.0


def test_linear_plastic_residual_indentation():
    """(7.15): alpha_r = alpha_m - [alpha_Y^1.5 + (K_Y/K_h)(alpha_m - alpha_Y)]^(2/3); unloading (7.11)."""
    law = EXAMPLES["linear_plastic"]
    a_Y, a_m = law.alpha_Y, 300.0 * law.alpha_Y
    K_Y = 1.5 * law.K_h * a_Y**0.5
    a_r = a_m - (a_Y**1.5 + K_Y / law.K_h * (a_m - a_Y)) ** (2.0 / 3.0)
    mem = _loaded(law, a_m)
    assert mem.alpha_residual == pytest.approx(a_r, rel=FORMULA_RTOL, abs=0)
    alpha = 0.5 * (a_r + a_m)
    assert law.force(alpha, -V0, mem) == pytest.approx(law.K_h * (alpha - a_r) ** 1.5, rel=FORMULA_RTOL, abs=0)


def test_power_plastic_unloading_constant_and_residual_indentation():
    """(7.25), (7.33), (7.38), (7.43), written with E' as in the thesis."""
    law = EXAMPLES["power_plastic"]
    Ep = plane_strain_modulus(E, NU)
    a_Y, a_fp = law.alpha_Y, law.alpha_fp
    a_m = 0.5 * (a_Y + a_fp)
    F_m = law.K_hY * (a_m**law.n - a_Y**law.n) + law.K_h * a_Y**1.5
    a2 = (1.0 + (a_m - a_Y) / (a_fp - a_Y)) * a_m * R
    K_h2 = 2.0 / 3.0 * Ep * np.sqrt(2.0 * Ep * a2**1.5 / (3.0 * F_m))
    a_r = a_m - (F_m / K_h2) ** (2.0 / 3.0)
    mem = _loaded(law, a_m)
    assert law.force(a_m, 0.0, law.onset(V0)) == pytest.approx(F_m, rel=FORMULA_RTOL, abs=0)
    assert mem.alpha_residual == pytest.approx(a_r, rel=FORMULA_RTOL, abs=0)
    alpha = 0.5 * (a_r + a_m)
    assert law.force(alpha, -V0, mem) == pytest.approx(K_h2 * (alpha - a_r) ** 1.5, rel=FORMULA_RTOL, abs=0)


@pytest.mark.parametrize("name", PLASTIC)
def test_no_crater_without_yield(name):
    law = EXAMPLES[name]
    mem = _loaded(law, 0.5 * law.alpha_Y)
    assert mem.alpha_residual == 0.0
    assert law.force(0.3 * law.alpha_Y, -V0, mem) == pytest.approx(law.K_h * (0.3 * law.alpha_Y) ** 1.5, rel=FORMULA_RTOL, abs=0)


@pytest.mark.parametrize("name", PLASTIC)
@pytest.mark.parametrize("depth", DEPTHS)
def test_loop_area_is_the_dissipated_energy(name, depth):
    """Area between loading and unloading curves (quadrature of the force) = work - recoverable energy."""
    law, a_m, fresh, mem = _loaded_to_depth(name, depth)
    load, unload = _loop_works(law, fresh, mem, a_m)
    assert law.elastic_energy(a_m, mem) == pytest.approx(unload, rel=QUAD_RTOL)
    assert load - law.elastic_energy(a_m, mem) == pytest.approx(load - unload, rel=QUAD_RTOL, abs=QUAD_RTOL * load)
    assert (load - unload > QUAD_RTOL * load) == (depth > 1.0), "a loop without yield, or none with it"


@pytest.mark.parametrize("name", PLASTIC)
def test_impact_loss_equals_the_loop_area(name):
    law = EXAMPLES[name]
    out = achieved_restitution(law, M_EFF, V0)
    mem = out.memory
    load, unload = _loop_works(law, law.onset(V0), mem, mem.alpha_max)
    assert out.energy_lost == pytest.approx(load - unload, rel=QUAD_RTOL)


def test_power_plastic_loses_less_than_linear_plastic():
    """Thesis conclusion 7 (and Table 8.4's losses): the power-plastic law is stiffer and loses less."""
    lin, pw = (achieved_restitution(EXAMPLES[n], M_EFF, V0) for n in ("linear_plastic", "power_plastic"))
    assert pw.energy_lost < lin.energy_lost and pw.peak_force > lin.peak_force and pw.duration < lin.duration


def test_linear_plastic_with_its_own_unloading_constant_is_eq_7_14():
    base = EXAMPLES["linear_plastic"]
    K_h2 = 1.7 * base.K_h
    law = type(base)(base.K_h, base.alpha_Y, K_h2)
    a_Y, a_m = law.alpha_Y, 50.0 * law.alpha_Y
    K_Y = 1.5 * law.K_h * a_Y**0.5
    a_r = a_m - ((law.K_h * a_Y**1.5 + K_Y * (a_m - a_Y)) / K_h2) ** (2.0 / 3.0)
    assert _loaded(law, a_m).alpha_residual == pytest.approx(a_r, rel=FORMULA_RTOL, abs=0)
    with pytest.raises(ValueError, match="negative crater"):
        type(base)(base.K_h, base.alpha_Y, 0.5 * base.K_h)
