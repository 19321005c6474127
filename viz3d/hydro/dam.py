"""A flexible dam coupled to its reservoir: crest frequency response and time response to ground motion.

The dam is a cantilever bar of ``viz3d.flexible`` clamped at its base: the bar axis is the height
y above the foundation (= reservoir bottom), its deflection w(y) = Phi(y) q is the horizontal
displacement of the upstream face relative to the ground, positive towards the reservoir. Modes
are mass normalised (M = I, K = diag(omega_i^2)); ``width`` is the length of dam the bar stands for
(the reservoir's forces are per metre).

With the ground acceleration a_g exp(j omega t), the face's total acceleration is
a_g + sum_j phi_j q_dd_j, so the pressure is ``p = p_0 a_g + sum_j p_j q_dd_j`` (p_0: rigid wall,
phi = 1) and the generalized force of the water on mode i is ``-width int_0^h phi_i p dy``
(the pressure pushes the face away from the water). Modal equations (docs/hydro.md, "Coupled dam"):

    [K + j omega C - omega^2 (I + width A_qq(omega))] q = -(L + width A_q0(omega)) a_g
      = [K + j omega C - omega^2 I + S(omega)] q,

A the ``added_mass`` matrix of the shapes (phi_1..phi_n, 1) on the wetted height, S = -omega^2
width A_qq the reservoir's dynamic stiffness, L_i = int rho A phi_i dy the modal participation
(``BarModel.S1``), C = diag(2 zeta omega_i) modal viscous damping. Crest: u_c = Phi(H) q (relative),
total acceleration a_g - omega^2 u_c. ``reservoir=None`` is the empty reservoir.

Time response: the record is zero padded, transformed by FFT, multiplied by the crest frequency
response and transformed back, with an exponential window (frequencies omega_k - j eta) so that the
response wrapped around the periodic transform is at most PAD_DECAY of its peak (``time_response``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray
from viz3d.flexible import BarModel, Material, Section, analytic_modes
from viz3d.hydro.records import GroundMotion
from viz3d.hydro.reservoir import DEFAULT_RTOL, Reservoir, SeriesResult, added_mass, pressure
from viz3d.hydro.shapes import SmoothShapes

#: Mass concrete of Pine Flat dam as Chopra and co-workers model it: E = 3.25e6 psi = 22.4 GPa,
#: unit weight 155 lb/ft^3 (2483 kg/m^3), Poisson's ratio 0.2.
CONCRETE = Material(E=22.4e9, rho=2483.0, nu=0.2)
#: Modal viscous damping ratio of the example dam (5 %, the usual value for concrete dams).
DEFAULT_DAMPING_RATIO = 0.05
#: The example: a 100 m high wall of constant 40 m thickness, full reservoir of the seed (h = 100 m):
#: empty-reservoir omega_1 = 11.0 rad/s, about half the first cut-off 23.45 rad/s (Chopra's typical
#: ratio of about 2); Timoshenko, five modes.
EXAMPLE_HEIGHT, EXAMPLE_THICKNESS, EXAMPLE_MODES = 100.0, 40.0, 5
#: Wrap-around allowed in the FFT time response, relative to the peak response (exponential window:
#: eta T = ln(1 / PAD_DECAY)); also the decay of the free vibration over the default zero padding.
PAD_DECAY = 1e-6
#: Relative tolerance on M = I (mass-normalised modes are built to quadrature round-off).
MASS_NORMALISED_RTOL = 1e-8
#: A compressible fundamental frequency is sought below this fraction of the first cut-off frequency.
CUTOFF_MARGIN = 1.0 - 1e-9
#: Frequencies within this relative distance of a cut-off (rigid bottom), where the rigid-wall terms are
#: infinite, are moved this far above it. The flexible dam's response is continuous there (it behaves
#: like a + b sqrt|omega - omega_n|), so the move changes it by O(sqrt(CUTOFF_NUDGE omega_n)): about 1e-6
#: relative for the example dam.
CUTOFF_NUDGE = 1e-14


@dataclass(frozen=True)
class Dam:
    """A cantilever dam in its modal coordinates.

    Attributes
    ----------
    bar : BarModel
        Bending model clamped at x = 0 (the base), mass normalised (M = I), deflection towards the
        reservoir positive; the bar axis is the height [m].
    damping_ratio : float
        Modal viscous damping ratio zeta of every mode [-].
    width : float
        Length of dam represented by the bar [m] (section area / depth for a rectangle 1 m wide).
    """

    bar: BarModel
    damping_ratio: float = DEFAULT_DAMPING_RATIO
    width: float = 1.0

    def __post_init__(self):
        if self.bar.kind != "bending" or self.bar.supports[0] != "clamped":
            raise ValueError(f"a dam is a bending bar clamped at its base, got {self.bar.kind} {self.bar.supports}")
        if not np.allclose(self.bar.M, np.eye(self.bar.n), rtol=0.0, atol=MASS_NORMALISED_RTOL):
            raise ValueError("the dam's bar model must be mass normalised (M = I); use normalization='mass'")
        if not (self.damping_ratio >= 0 and self.width > 0):
            raise ValueError(f"damping ratio must be >= 0 and width > 0, got {self.damping_ratio}, {self.width}")

    @property
    def height(self) -> float:
        """H [m]."""
        return self.bar.length

    @property
    def n_modes(self) -> int:
        return self.bar.n

    @property
    def omega(self) -> FloatArray:
        """Empty-reservoir natural frequencies omega_i = sqrt(K_ii), shape (n,) [rad/s]."""
        return np.sqrt(np.diag(self.bar.K))

    @property
    def participation(self) -> FloatArray:
        """L_i = int rho A phi_i dy, shape (n,) [sqrt(kg)]: modal force per unit ground acceleration is -L_i."""
        return self.bar.S1


def cantilever_dam(height: float = EXAMPLE_HEIGHT, thickness: float = EXAMPLE_THICKNESS, n_modes: int = EXAMPLE_MODES, *,
                   material: Material = CONCRETE, theory: str = "timoshenko",
                   damping_ratio: float = DEFAULT_DAMPING_RATIO) -> Dam:
    """A wall of constant ``thickness`` [m] and 1 m width, as a clamped-free bar of analytic modes."""
    bar = analytic_modes(theory, height, material, Section.rectangle(1.0, thickness), n_modes, ("clamped", "free"))
    return Dam(bar, damping_ratio, width=1.0)


def wetted_shapes(dam: Dam, depth: float) -> SmoothShapes:
    """The dam's modes on the wetted height [0, depth], then the uniform shape 1 (ground motion): n + 1 shapes."""
    if not 0 < depth <= dam.height * (1 + 1e-12):
        raise ValueError(f"water depth {depth} m must be within the dam height {dam.height} m")

    def shapes(y):
        return np.column_stack([dam.bar.displacement(np.minimum(y, dam.height)), np.ones(np.size(y))])

    return SmoothShapes(shapes, float(depth), dam.n_modes + 1)


def hydrodynamic_terms(dam: Dam, reservoir: Reservoir, omega, *, rtol: float = DEFAULT_RTOL):
    """Width-scaled added mass of the modes and their coupling to the ground motion.

    Returns
    -------
    A_qq : ndarray, shape (w, n, n)
        width * int phi_i p_j dy [dimensionless for mass-normalised modes]; S = -omega^2 A_qq.
    A_q0 : ndarray, shape (w, n)
        width * int phi_i p_0 dy [sqrt(kg)]: the rigid-wall pressure's modal force per unit a_g.
    A_00 : ndarray, shape (w,)
        width * int p_0 dy [kg]: force on a rigid dam per unit a_g.
    n_terms : int
    """
    A = added_mass(reservoir, wetted_shapes(dam, reservoir.depth), omega, rtol=rtol)
    n, w = dam.n_modes, dam.width
    return w * A.value[:, :n, :n], w * A.value[:, :n, n], w * A.value[:, n, n], A.n_terms


@dataclass(frozen=True)
class FrequencyResponse:
    """Response of the dam to a unit harmonic ground acceleration a_g = exp(j omega t).

    Attributes
    ----------
    omega : ndarray, shape (w,)
        [rad/s]; complex (Im omega < 0) when ``time_response`` evaluates along a shifted line.
    modal : ndarray, shape (w, n)
        Modal amplitudes q per unit a_g [sqrt(kg) s^2].
    crest_displacement : ndarray, shape (w,)
        Crest displacement relative to the ground per unit a_g [s^2].
    crest_acceleration : ndarray, shape (w,)
        Total crest acceleration per unit a_g [-] (1 at omega = 0 is the rigid motion).
    hydrodynamic_force : ndarray, shape (w,)
        Force of the water on the dam, total over ``width``, positive downstream (-x), per unit a_g [kg].
    base_shear : ndarray, shape (w,)
        Force of the foundation on the dam, positive towards the reservoir (+x), per unit a_g [kg]:
        ``int m a_total dy + hydrodynamic_force = mass - omega^2 L q + hydrodynamic_force`` (its
        static value, omega = 0, is the dam's mass plus the water's rigid-wall added mass).
    n_terms : int
        Series terms of the reservoir (0 for an empty reservoir).
    """

    omega: FloatArray
    modal: np.ndarray
    crest_displacement: np.ndarray
    crest_acceleration: np.ndarray
    hydrodynamic_force: np.ndarray
    base_shear: np.ndarray
    n_terms: int


def off_cutoff(reservoir: Reservoir, omega: FloatArray) -> FloatArray:
    """``omega`` with the values within CUTOFF_NUDGE (relative) of a rigid-bottom cut-off moved that far above it."""
    if not (reservoir.compressible and reservoir.rigid_bottom) or omega.size == 0:
        return omega
    w = np.abs(omega)
    n = np.round(w * reservoir.depth / (np.pi * reservoir.sound_speed) + 0.5)  # omega_n = (n - 1/2) pi c / h
    nearest = (2.0 * np.maximum(n, 1.0) - 1.0) * np.pi * reservoir.sound_speed / (2.0 * reservoir.depth)
    near = np.abs(w - nearest) <= CUTOFF_NUDGE * nearest
    return np.where(near, np.sign(omega) * nearest * (1.0 + CUTOFF_NUDGE), omega)


def frequency_response(dam: Dam, reservoir: Reservoir | None, omega, *, rtol: float = DEFAULT_RTOL) -> FrequencyResponse:
    """Crest response of ``dam`` to horizontal ground acceleration; ``reservoir=None`` for an empty one."""
    omega = np.atleast_1d(np.asarray(omega))
    if reservoir is not None and not np.iscomplexobj(omega):
        omega = off_cutoff(reservoir, omega.astype(float))
    n = dam.n_modes
    w2 = (omega**2)[:, None, None]
    D = dam.bar.K[None] + 1j * omega[:, None, None] * np.diag(2.0 * dam.damping_ratio * dam.omega)[None] - w2 * np.eye(n)
    load = -np.broadcast_to(dam.participation, (omega.size, n)).astype(complex)
    force, n_terms = np.zeros(omega.size, dtype=complex), 0
    if reservoir is not None:
        A_qq, A_q0, A_00, n_terms = hydrodynamic_terms(dam, reservoir, omega, rtol=rtol)
        D = D - w2 * A_qq
        load = load - A_q0
    q = np.linalg.solve(D, load[..., None])[..., 0]
    if reservoir is not None:  # width int p dy, p = p_0 a_g + sum_j p_j q_dd_j: pushes the dam downstream
        force = A_00 - omega**2 * np.einsum("wj,wj->w", A_q0, q)
    crest = q @ dam.bar.displacement([dam.height])[0]
    shear = dam.bar.mass - omega**2 * (q @ dam.participation) + force
    return FrequencyResponse(omega, q, crest, 1.0 - omega**2 * crest, force, shear, n_terms)


def fundamental_frequency(dam: Dam, reservoir: Reservoir | None = None, *, rtol: float = DEFAULT_RTOL) -> float:
    """Lowest undamped natural frequency of the dam-water system [rad/s].

    Empty: omega_1 of the bar. Incompressible water: the lowest root of det(K - omega^2 (I + A_qq)) = 0,
    A_qq constant. Compressible water over a rigid bottom: A_qq(omega) is real below the first cut-off
    omega_r = pi c / 2h, and the root of omega^2 = lambda_min(K, I + A_qq(omega)) below omega_r is found
    by Brent's method (it exists when the dam's added mass grows without bound at omega_r). An absorbing
    bottom has no real natural frequency: read the peak of ``frequency_response`` instead.
    """
    from scipy.linalg import eigh
    from scipy.optimize import brentq
    if reservoir is None:
        return float(dam.omega.min())
    if not reservoir.rigid_bottom:
        raise ValueError("an absorbing bottom damps every mode: no real natural frequency")

    def lowest(omega: float) -> float:
        A_qq = hydrodynamic_terms(dam, reservoir, omega, rtol=rtol)[0][0].real
        return float(np.sqrt(eigh(dam.bar.K, np.eye(dam.n_modes) + A_qq, eigvals_only=True)[0]))

    if not reservoir.compressible:
        return lowest(0.0)
    omega_r = CUTOFF_MARGIN * float(reservoir.cutoff_frequencies(1)[0])
    if lowest(omega_r) >= omega_r:
        raise ValueError(f"no natural frequency below the first cut-off {omega_r:.4g} rad/s")
    return float(brentq(lambda w: lowest(w) - w, 0.0, omega_r, xtol=1e-10 * omega_r))


@dataclass(frozen=True)
class TimeResponse:
    """Crest response to a ground-acceleration record.

    Attributes
    ----------
    t : ndarray, shape (n,)
        [s].
    ground_acceleration : ndarray, shape (n,)
        a_g [m/s^2].
    crest_displacement : ndarray, shape (n,)
        Relative to the ground [m].
    crest_acceleration : ndarray, shape (n,)
        Total [m/s^2].
    hydrodynamic_force : ndarray, shape (n,)
        Force of the water on the dam, positive downstream [N] (``FrequencyResponse``).
    base_shear : ndarray, shape (n,)
        Force of the foundation on the dam, positive towards the reservoir [N].
    n_fft : int
        Padded length of the transform.
    n_terms : int
        Series terms of the reservoir.
    """

    t: FloatArray
    ground_acceleration: FloatArray
    crest_displacement: FloatArray
    crest_acceleration: FloatArray
    hydrodynamic_force: FloatArray
    base_shear: FloatArray
    n_fft: int
    n_terms: int


def padding(dam: Dam) -> float:
    """Zero padding [s] after which the slowest mode's free vibration has decayed by PAD_DECAY through
    structural damping (0 for an undamped dam: the exponential window alone then bounds the wrap-around)."""
    if dam.damping_ratio == 0:
        return 0.0
    return float(np.log(1.0 / PAD_DECAY) / (dam.damping_ratio * dam.omega.min()))


@dataclass(frozen=True)
class WindowedSpectrum:
    """A record's exponentially windowed transform (``windowed_spectrum``), and its way back.

    Attributes
    ----------
    omega : ndarray, shape (m,)
        omega_k - j eta, k = 0..n_fft/2 [rad/s].
    transform : ndarray, shape (m,)
        rfft of a_g(t) exp(-eta t), zero padded to n_fft [m/s].
    window : ndarray, shape (n,)
        exp(-eta t) at the record's samples.
    n_fft : int
    """

    omega: np.ndarray
    transform: np.ndarray
    window: FloatArray
    n_fft: int

    def response(self, transfer: np.ndarray) -> FloatArray:
        """Time history of the response whose transfer functions (per unit a_g) are ``transfer``:
        shape (m, ...) -> (n, ...), the record's samples [the transfer's unit times m/s^2]."""
        from scipy.fft import irfft
        shaped = self.transform.reshape((-1,) + (1,) * (transfer.ndim - 1))
        out = irfft(transfer * shaped, self.n_fft, axis=0)[: self.window.size]
        return out / self.window.reshape((-1,) + (1,) * (transfer.ndim - 1))


def windowed_spectrum(dam: Dam, record: GroundMotion, pad: float | None = None) -> WindowedSpectrum:
    """Zero pad ``record`` by ``pad`` seconds (default ``padding``, at least the record's length) to n_fft
    samples, period T = n_fft dt, and transform it with the exponential window eta T = ln(1 / PAD_DECAY)
    (``time_response`` says why)."""
    from scipy.fft import next_fast_len, rfft, rfftfreq
    a, dt = record.acceleration, record.dt
    pad = max(padding(dam), record.duration) if pad is None else float(pad)
    n_fft = next_fast_len(a.size + int(np.ceil(pad / dt)), real=True)
    eta = np.log(1.0 / PAD_DECAY) / (n_fft * dt)
    window = np.exp(-eta * record.t)
    omega = 2.0 * np.pi * rfftfreq(n_fft, dt) - 1j * eta
    return WindowedSpectrum(omega, rfft(a * window, n_fft), window, n_fft)


def time_response(dam: Dam, reservoir: Reservoir | None, record: GroundMotion, *, rtol: float = DEFAULT_RTOL,
                  pad: float | None = None) -> TimeResponse:
    """Crest response to ``record`` by FFT with an exponential window (Kausel's method).

    The record is zero padded by ``pad`` seconds (default ``padding``, at least the record's length) to
    n_fft samples, period T = n_fft dt. A discrete transform computes periodic responses; the response
    to ``a_g(t) exp(-eta t)`` is ``u(t) exp(-eta t)``, obtained from the frequency response at
    ``omega_k - j eta``, so the copies wrapped in from later periods arrive multiplied by exp(-eta m T).
    With eta T = ln(1 / PAD_DECAY) the wrap-around is at most PAD_DECAY / (1 - PAD_DECAY) of max |u|
    for any bounded response: also over a rigid-bottom compressible reservoir, whose response decays
    only algebraically (square-root branch points at the cut-off frequencies). Multiplying back by
    exp(eta t) amplifies round-off by at most 1 / PAD_DECAY.
    """
    spectrum = windowed_spectrum(dam, record, pad)
    r = frequency_response(dam, reservoir, spectrum.omega, rtol=rtol)
    u, acc, force, shear = spectrum.response(np.stack([r.crest_displacement, r.crest_acceleration,
                                                       r.hydrodynamic_force, r.base_shear], axis=1)).T
    return TimeResponse(record.t, record.acceleration, u, acc, force, shear, spectrum.n_fft, r.n_terms)


def dam_pressure(dam: Dam, reservoir: Reservoir, omega, y, x=0.0, *, rtol: float = DEFAULT_RTOL) -> SeriesResult:
    """Pressure in the reservoir per unit harmonic ground acceleration, the dam responding.

    The face's acceleration is a_g + sum_j phi_j q_dd_j, so ``p = p_0 + sum_j p_j (-omega^2 q_j)`` with
    p_j the ``pressure`` of shape j (p_0: the rigid wall) and q the ``frequency_response``'s modal
    amplitudes: ``pressure`` of the ``wetted_shapes`` with that combination. Parameters as
    ``pressure``; ``value`` (w, p) complex [Pa / (m/s^2)].
    """
    response = frequency_response(dam, reservoir, omega, rtol=rtol)
    omega = response.omega  # moved off the cut-offs as the response was
    accelerations = np.column_stack([-(omega**2)[:, None] * response.modal, np.ones(omega.size)])  # (w, n + 1)
    return pressure(reservoir, wetted_shapes(dam, reservoir.depth), omega, y, x, rtol=rtol, combination=accelerations)


def pressure_history(dam: Dam, reservoir: Reservoir, record: GroundMotion, y, x=0.0, *, omega_max: float,
                     rtol: float = DEFAULT_RTOL, pad: float | None = None) -> tuple[FloatArray, FloatArray, int]:
    """Pressure p(x, y, t) during ``record`` [Pa], low-passed at ``omega_max`` [rad/s].

    ``dam_pressure`` on the windowed spectrum (``windowed_spectrum``) up to ``omega_max``, zero above:
    for drawing frames every pi / omega_max seconds, the low-pass is their anti-aliasing filter (and
    keeps the cost to the frequencies drawn). Returns (t (n,) [s], p (n, len(y)) [Pa], series terms).
    """
    spectrum = windowed_spectrum(dam, record, pad)
    kept = spectrum.omega.real <= omega_max
    transfer = np.zeros((spectrum.omega.size, np.size(y)), dtype=complex)
    field = dam_pressure(dam, reservoir, spectrum.omega[kept], y, x, rtol=rtol)
    transfer[kept] = field.value
    return record.t, spectrum.response(transfer), field.n_terms
