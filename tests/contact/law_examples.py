"""One representative instance of every registered normal law, for the parametrised tests.

A steel sphere of radius 25 mm on a steel flat (thesis sec. 7.3.5 and 8.4: R = 25 mm, E = 210 GPa,
nu = 0.3, sigma_Y = 0.64 GPa, the values that reproduce Table 7.1), struck by the thesis's
2.133 kg impactor at 1 m/s. Registering a law without adding it here fails
``test_every_registered_law_has_an_example``.
"""

from viz3d.contact.laws import (
    Flores,
    Hertz,
    HuntCrossley,
    LankaraniNikravesh,
    Linear,
    LinearPlastic,
    PowerPlastic,
    YigitChristoforou,
)
from viz3d.contact.parameters import hertz_stiffness_sphere_plane

R, E, NU, SIGMA_Y = 0.025, 210e9, 0.3, 0.64e9
M_EFF, V0 = 2.133, 1.0
K_HERTZ = hertz_stiffness_sphere_plane(R, E, NU, E, NU)
#: Linear penalty: the Hertz secant stiffness at the Hertz peak indentation of this impact (order 1e8 N/m).
K_LINEAR = 2.5e8

EXAMPLES = {
    "linear": Linear(K_LINEAR),
    "hertz": Hertz(K_HERTZ),
    "hunt_crossley": HuntCrossley(K_HERTZ, 1.5, restitution=0.6),
    "lankarani_nikravesh": LankaraniNikravesh(K_HERTZ, 1.5, restitution=0.6),
    "flores": Flores(K_HERTZ, 1.5, restitution=0.6),
    "yigit_christoforou": YigitChristoforou.from_material(R, E, NU, SIGMA_Y),
    "linear_plastic": LinearPlastic.from_material(R, E, NU, SIGMA_Y),
    "power_plastic": PowerPlastic.from_material(R, E, NU, SIGMA_Y),
}
