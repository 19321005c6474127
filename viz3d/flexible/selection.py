"""How many modes a bar needs for an impact: frequency band, truncation error, theory validity.

Criterion ("model economy"):

1. **Band.** A contact force of duration t_c has little energy above a few times 2 pi / t_c; modes
   above the band respond quasi-statically. ``contact_band`` gives omega_max = f 2 pi / t_c with
   f = ``CONTACT_BAND_FACTOR``; every elastic mode with omega <= omega_max is kept.
2. **Truncation error.** The omitted modes still deflect quasi-statically under the contact force;
   their share of the point flexibility at the contact point,

       G_res(n) = sum_{i > n} phi_i(x_c)^2 / omega_i^2      (mass-normalised modes),

   is the *residual flexibility* (static correction, mode-acceleration method). Its ratio to the
   full flexibility G = sum_i phi_i(x_c)^2 / omega_i^2 (= the static flexibility of a supported
   bar; the inertia-relief flexibility of a free one) is the truncation error estimate. With a
   tolerance, the smallest n with G_res(n) <= tol G is kept. A solver may add G_res as a spring in
   series with the contact to recover the static part of the omitted modes.
3. **Theory validity.** The wavelength 2 pi / k of the highest retained mode (k from the theory's
   dispersion relation) is compared with the depth: Euler-Bernoulli is flagged when it is below
   ``EB_MIN_WAVELENGTH_DEPTHS`` depths (thesis 5.2 and 8.4.1: shear and rotary inertia matter once
   the wavelength approaches the depth), together with the EB frequency error at that wavenumber
   from the Timoshenko dispersion relation.

The modes are those of a *reference* model that resolves the band (a fine FE mesh, or an analytic
set with many modes); the count is only as good as the reference's spectrum.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray
from viz3d.flexible.bar import BarModel, reduce, rigid_mode_count
from viz3d.flexible.modes import THEORY_CLASSES, EulerBernoulli, Timoshenko

#: omega_max = CONTACT_BAND_FACTOR * 2 pi / t_c. The Fourier amplitude of a half-sine pulse of
#: duration t_c relative to its static value is pi^2 |cos(w t_c / 2)| / |pi^2 - (w t_c)^2|; its
#: envelope at w t_c = 8 pi (factor 4) is 1 / 63 = 1.6 %.
CONTACT_BAND_FACTOR = 4.0
#: Flag Euler-Bernoulli below this wavelength / depth: at 10 depths the EB frequency of a steel
#: rectangle (k = 5/6, nu = 0.3) is 6 % above Timoshenko's (and 12 % for the thesis's 3rd
#: cantilever mode, Table 8.3, at 8 depths).
EB_MIN_WAVELENGTH_DEPTHS = 10.0
#: Only this lower fraction of a reference model's elastic spectrum is trusted (FE upper modes
#: are inaccurate); asking for more sets ``reference_exhausted``.
REFERENCE_USABLE_FRACTION = 0.5


def contact_band(t_c: float, factor: float = CONTACT_BAND_FACTOR) -> float:
    """Highest frequency omega_max = factor 2 pi / t_c [rad/s] excited by a contact of duration t_c [s]."""
    if not t_c > 0:
        raise ValueError(f"contact duration must be positive, got {t_c}")
    return factor * 2.0 * np.pi / t_c


@dataclass(frozen=True)
class ModeSelection:
    """Outcome of ``select_modes``.

    Attributes
    ----------
    n_modes : int
        Elastic modes to keep (0: the bar responds quasi-statically in the band).
    omega : ndarray, shape (n_modes,)
        Their frequencies [rad/s].
    omega_next : float
        First omitted elastic frequency [rad/s] (inf if the reference has no more).
    flexibility : float
        Full point flexibility G at the contact point [m/N].
    residual_flexibility : float
        G_res of the omitted modes [m/N].
    truncation_error : float
        G_res / G [-].
    wavelength : float
        Wavelength of the highest retained mode, 2 pi / k [m] (inf if n_modes = 0).
    eb_frequency_error : float or None
        omega_EB / omega_Timoshenko - 1 at that wavenumber (bending models), else None.
    eb_valid : bool or None
        wavelength >= EB_MIN_WAVELENGTH_DEPTHS depths (bending models), else None.
    reference_exhausted : bool
        n_modes exceeds the trusted part of the reference's spectrum: refine the reference.
    """

    n_modes: int
    omega: FloatArray
    omega_next: float
    flexibility: float
    residual_flexibility: float
    truncation_error: float
    wavelength: float
    eb_frequency_error: float | None
    eb_valid: bool | None
    reference_exhausted: bool


def modal_flexibilities(reference: BarModel, x_contact: float) -> tuple[FloatArray, FloatArray]:
    """Elastic frequencies omega_i (m,) [rad/s] and their point flexibilities phi_i(x_c)^2 / omega_i^2 (m,) [m/N]."""
    modes = reduce(reference, reference.n - rigid_mode_count(reference.kind, reference.supports), drop_rigid=True)
    omega = np.sqrt(np.diag(modes.K))
    phi = modes.displacement([x_contact])[0]
    return omega, phi**2 / omega**2


def wavenumber(model: BarModel, omega: float) -> float:
    """Wavenumber k [1/m] of a free wave at ``omega`` in the model's theory (lower branch for Timoshenko)."""
    theory = THEORY_CLASSES[model.theory](model.length, model.material, model.section)
    return float(theory.columns(omega).rates[0])


def eb_frequency_error(model: BarModel, k: float) -> float:
    """omega_EB(k) / omega_Timoshenko(k) - 1 for the model's material and section at wavenumber k [1/m]."""
    s = k * model.length
    eb = EulerBernoulli(model.length, model.material, model.section)
    timo = Timoshenko(model.length, model.material, model.section)
    return eb.omega(s) / timo.omega(s) - 1.0


def select_modes(
    reference: BarModel,
    x_contact: float,
    *,
    omega_max: float | None = None,
    tol: float | None = None,
    min_wavelength_depths: float = EB_MIN_WAVELENGTH_DEPTHS,
) -> ModeSelection:
    """Number of elastic modes for a contact at ``x_contact`` [m] (see the module docstring).

    Parameters
    ----------
    reference : BarModel
        A model that resolves the band (e.g. ``fe_model`` with 4x more elements than modes needed).
    x_contact : float
        Contact point [m].
    omega_max : float, optional
        Band limit [rad/s], e.g. ``contact_band(t_c)``; keeps every mode up to it.
    tol : float, optional
        Largest acceptable truncation error G_res / G; keeps the fewest modes meeting it.
        With both, the larger count wins.
    min_wavelength_depths : float
        Euler-Bernoulli validity threshold on wavelength / depth.
    """
    if omega_max is None and tol is None:
        raise ValueError("give omega_max (a frequency band) and/or tol (a truncation error)")
    omega, g = modal_flexibilities(reference, x_contact)
    residual = np.append(np.cumsum(g[::-1])[::-1], 0.0)  # residual[n] = sum_{i >= n} g_i
    n = 0
    if omega_max is not None:
        n = int(np.count_nonzero(omega <= omega_max))
    if tol is not None:
        n = max(n, int(np.argmax(residual <= tol * residual[0])))
    return _selection(reference, omega, residual, n, min_wavelength_depths)


def _selection(reference: BarModel, omega: FloatArray, residual: FloatArray, n: int, depths: float) -> ModeSelection:
    k = wavenumber(reference, omega[n - 1]) if n > 0 else 0.0
    wavelength = 2.0 * np.pi / k if k > 0 else np.inf
    bending = reference.kind == "bending"
    return ModeSelection(
        n_modes=n,
        omega=omega[:n],
        omega_next=float(omega[n]) if n < len(omega) else np.inf,
        flexibility=float(residual[0]),
        residual_flexibility=float(residual[n]),
        truncation_error=float(residual[n] / residual[0]),
        wavelength=float(wavelength),
        eb_frequency_error=eb_frequency_error(reference, k) if bending and n > 0 else (0.0 if bending else None),
        eb_valid=bool(wavelength >= depths * reference.section.depth) if bending else None,
        reference_exhausted=n > REFERENCE_USABLE_FRACTION * len(omega),
    )
