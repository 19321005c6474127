"""What a law allows and how finely a contact must be resolved (viz3d.contact.resolution).

References: closed forms derived here from the law (linear: half period pi sqrt(m/K); Hertz:
energy balance for the indentation and the exact duration integral of ``viz3d.contact.exact``),
and the one-degree-of-freedom impact integrated at rtol 1e-12 (``achieved_restitution``), a
different method from the closed forms under test.
"""

from dataclasses import replace

import numpy as np
import pytest
from law_examples import EXAMPLES, M_EFF, V0

from viz3d.contact.exact import hertz_impact
from viz3d.contact.laws import NORMAL_LAWS, Hertz, Linear
from viz3d.contact.resolution import (
    admissible_indentation,
    contact_time_scale,
    free_impact_restitution,
    indentation_diagnosis,
    load_restitution_slack,
    restitution_diagnosis,
)
from viz3d.contact.single_impact import achieved_restitution

#: Root finding to ALPHA_RTOL = 1e-10; the 1-DOF reference is integrated at rtol 1e-12.
ROOT_TOL = 1e-9
#: The secant half period at the Hertz peak over the exact Hertz duration: pi sqrt(4/5) / 2.94328
#: (energy balance K alpha_m^2.5 / 2.5 = m v^2 / 2, secant stiffness K alpha_m^0.5).
HERTZ_SECANT_RATIO = np.pi * np.sqrt(0.8) / 2.94328
#: The 2.94328 of the digest (Appendix B) carries 6 digits.
DIGEST_6_DIGITS = 5e-6


def test_time_scale_of_a_linear_contact_is_its_half_period():
    law = Linear(2.5e8)
    assert contact_time_scale(law, M_EFF, V0) == pytest.approx(np.pi * np.sqrt(M_EFF / 2.5e8), rel=ROOT_TOL)


def test_time_scale_of_hertz_is_the_secant_half_period():
    law = EXAMPLES["hertz"]
    exact = hertz_impact(law.stiffness, M_EFF, np.inf, V0).contact_time
    assert contact_time_scale(law, M_EFF, V0) / exact == pytest.approx(HERTZ_SECANT_RATIO, rel=DIGEST_6_DIGITS)


def test_time_scale_of_a_contact_pressed_by_a_load_alone():
    """No approach speed, a weight F: the quasi-static indentation (F/K)^(2/3) and its secant."""
    law, F = Hertz(1.5e10), 0.3227
    alpha = (F / law.stiffness) ** (2 / 3)
    assert contact_time_scale(law, 0.0329, 0.0, force=F) == pytest.approx(np.pi * np.sqrt(0.0329 * alpha / F),
                                                                           rel=ROOT_TOL)
    assert contact_time_scale(law, 0.0329, 0.0) == np.inf  # nothing presses: no time scale


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_a_contact_the_joints_hold_has_no_time_scale(name):
    """An infinite effective mass (``ContactEvents.effective_mass`` of a contact whose normal the
    joints hold, its mobility zero up to round-off of either sign): no time scale, whatever the load
    or speed, and no nan from ``inf * 0`` on the way."""
    with np.errstate(all="raise"):
        assert contact_time_scale(EXAMPLES[name], np.inf, 0.0, force=1e3) == np.inf
        assert contact_time_scale(EXAMPLES[name], np.inf, V0) == np.inf


def test_admissible_indentation_closed_forms():
    E = 0.5 * M_EFF * V0**2
    hertz, linear = EXAMPLES["hertz"], EXAMPLES["linear"]
    assert admissible_indentation(hertz, E) == pytest.approx((2.5 * E / hertz.stiffness) ** 0.4, rel=ROOT_TOL)
    assert admissible_indentation(linear, E) == pytest.approx(np.sqrt(2 * E / linear.stiffness), rel=ROOT_TOL)
    assert admissible_indentation(hertz, 0.0) == 0.0


@pytest.mark.parametrize("name", sorted(NORMAL_LAWS))
def test_no_free_impact_goes_deeper_than_the_energy_allows(name):
    """The bound is exact: the integrated impact's peak stays below it, and for laws that lose
    nothing on the way in (elastic, plastic loading stores part) it is reached by the elastic ones."""
    law = EXAMPLES[name]
    out = achieved_restitution(law, M_EFF, V0)
    bound = admissible_indentation(law, out.energy_in)
    assert out.peak_indentation <= bound * (1 + ROOT_TOL)
    if not law.dissipative:
        assert out.peak_indentation == pytest.approx(bound, rel=ROOT_TOL)


def test_a_crater_costs_nothing_to_re_enter():
    law = EXAMPLES["power_plastic"]
    after = achieved_restitution(law, M_EFF, V0).memory
    assert after.alpha_residual > 0
    assert admissible_indentation(law, 0.0, after) == after.alpha_residual
    assert admissible_indentation(law, 1e-3, after) > after.alpha_residual


@pytest.mark.parametrize("name", sorted(NORMAL_LAWS))
def test_free_impact_restitution_matches_the_integrated_impact(name):
    law = EXAMPLES[name]
    assert free_impact_restitution(law, M_EFF, V0) == pytest.approx(achieved_restitution(law, M_EFF, V0).restitution,
                                                                     abs=ROOT_TOL)


@pytest.mark.parametrize("name", ["hunt_crossley", "lankarani_nikravesh", "flores"])
@pytest.mark.parametrize("speed", [0.1, 1.0, 3.0])
def test_fixed_damping_factor_restitution_is_the_closed_form_at_chi_c_v0(name, speed):
    """F = K a^n (1 + c a_dot) is the rate law with chi = c v0: its restitution follows the closed form
    at each speed (steel on steel, c = 0.2664 s/m), checked against the integrated impact."""
    law = replace(EXAMPLES[name], damping_factor=0.2664)
    assert law.memoryless and law.dissipative
    integrated = achieved_restitution(law, M_EFF, speed).restitution
    assert free_impact_restitution(law, M_EFF, speed) == pytest.approx(integrated, abs=ROOT_TOL)
    assert integrated < free_impact_restitution(law, M_EFF, speed / 3) + ROOT_TOL  # faster: more damping


def test_slow_approach_below_the_laws_floor_uses_the_integrated_impact():
    """Below MIN_APPROACH_SPEED the rate laws damp less than e(chi) says: the check must know."""
    law = EXAMPLES["hunt_crossley"]
    slow = 1e-5
    assert free_impact_restitution(law, M_EFF, slow) == pytest.approx(achieved_restitution(law, M_EFF, slow).restitution,
                                                                      abs=ROOT_TOL)
    assert free_impact_restitution(law, M_EFF, slow) > free_impact_restitution(law, M_EFF, V0)


def test_load_slack_grows_with_the_load_and_the_duration():
    assert load_restitution_slack(9.81, 8e-5, 0.63) == pytest.approx(2 * 9.81 * 8e-5 / 0.63)
    assert load_restitution_slack(0.0, 8e-5, 0.63) == 0.0
    assert load_restitution_slack(9.81, 8e-5, 0.0) == np.inf


def test_diagnoses_name_the_contact_the_time_and_the_quantity():
    law = EXAMPLES["hertz"]
    text = indentation_diagnosis(1, 0.0639, 0.553, law, 6.45e-3, None)
    assert text.startswith("contact 1 at t = 0.0639 s: indentation 0.553 m exceeds the ")
    assert "hertz law allows with the energy available (0.00645 J" in text
    assert restitution_diagnosis(2, 0.17, 0.83, 0.8, 0.86, law, 0.52, 0.43) is None
    text = restitution_diagnosis(2, 0.17, -0.047, 0.8, 0.86, law, 0.52, -0.024)
    assert text.startswith("contact 2 at t = 0.17 s: restitution -0.047 outside the [0.8, 0.86]")
