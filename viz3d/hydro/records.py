"""Horizontal ground-acceleration records: a CSV reader and a synthetic record from a stated spectrum.

``GroundMotion`` is a uniformly sampled acceleration a_g(t_i), t_i = i dt [m/s^2], positive towards
the reservoir (+x of ``viz3d.hydro.reservoir``).

CSV files: lines starting with ``#`` are comments; the first other line is a header naming the
columns; values are separated by commas. The acceleration column is chosen by name (``column``);
the time column (``time_column``), if present, must be uniformly spaced (to ``TIME_STEP_RTOL`` of a
step), otherwise ``dt`` must be given. ``scale`` converts units (``STANDARD_GRAVITY`` for records in
g). Every error names the file, and where it applies the line and the column.

Synthetic records (``synthetic_record``) follow the spectral representation method (Shinozuka &
Deodatis 1991): a stationary signal

    a_s(t) = sum_k sqrt(2 G(omega_k) d_omega) cos(omega_k t + theta_k),   omega_k = k d_omega,

theta_k independent and uniform on [0, 2 pi) from a seeded generator, G the one-sided power
spectral density (variance = int_0^inf G d omega), here Kanai-Tajimi filtered white noise with the
Clough-Penzien high-pass factor (so that ground velocity and displacement stay bounded)

    G(omega) = S0 (1 + 4 zg^2 r^2) / ((1 - r^2)^2 + 4 zg^2 r^2) * rf^4 / ((1 - rf^2)^2 + 4 zf^2 rf^2),
    r = omega / omega_g,  rf = omega / omega_f,

multiplied by the Jennings-Housner-Tsai (1968) envelope (t / t1)^2, 1, exp(-decay (t - t2)), and
scaled to a stated peak ground acceleration. d_omega = 2 pi / (n dt) puts every omega_k on a
frequency of the discrete Fourier transform of the n samples, so the record is one inverse FFT.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from viz3d._typing import FloatArray

#: g [m/s^2] (CGPM 1901), to read records given in units of g.
STANDARD_GRAVITY = 9.80665
#: Largest deviation of a time stamp from the uniform grid, as a fraction of the step.
TIME_STEP_RTOL = 1e-3
#: The record shipped with viz3d (``shipped_record``) and how it was made (``write_shipped_record``).
SHIPPED_RECORD = Path(__file__).parent / "data" / "synthetic_kanai_tajimi.csv"
SHIPPED_SEED = 13
SHIPPED_DURATION = 20.0  # s
SHIPPED_DT = 0.01  # s
SHIPPED_PGA = 0.3 * STANDARD_GRAVITY  # m/s^2
#: Significant digits written to CSV files.
CSV_DIGITS = 10


@dataclass(frozen=True)
class GroundMotion:
    """A uniformly sampled horizontal ground acceleration.

    Attributes
    ----------
    dt : float
        Sampling step [s].
    acceleration : ndarray, shape (n,)
        a_g(i dt) [m/s^2], positive towards the reservoir.
    name : str
        Where it came from.
    """

    dt: float
    acceleration: FloatArray
    name: str = ""

    def __post_init__(self):
        a = np.asarray(self.acceleration, dtype=float)
        if a.ndim != 1 or a.size < 2 or not np.all(np.isfinite(a)):
            raise ValueError(f"{self.name or 'record'}: acceleration must be a finite 1-D array of at least 2 samples")
        if not self.dt > 0:
            raise ValueError(f"{self.name or 'record'}: time step must be positive, got {self.dt}")
        a.flags.writeable = False
        object.__setattr__(self, "acceleration", a)

    @property
    def t(self) -> FloatArray:
        """Sample times i dt, shape (n,) [s]."""
        return self.dt * np.arange(self.acceleration.size)

    @property
    def duration(self) -> float:
        """(n - 1) dt [s]."""
        return self.dt * (self.acceleration.size - 1)

    @property
    def pga(self) -> float:
        """Peak ground acceleration max |a_g| [m/s^2]."""
        return float(np.abs(self.acceleration).max())


# ----------------------------------------------------------------------------------------------
# CSV
# ----------------------------------------------------------------------------------------------
def _rows(path: Path):
    """(line number, fields) of the non-comment, non-blank lines of a CSV file."""
    with path.open(newline="") as f:
        for number, fields in enumerate(csv.reader(f), start=1):
            if not fields or not "".join(fields).strip() or fields[0].lstrip().startswith("#"):
                continue
            yield number, [v.strip() for v in fields]


def _number(text: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{where}: {text!r} is not a number") from None
    if not np.isfinite(value):
        raise ValueError(f"{where}: {text!r} is not finite")
    return value


def read_csv(path, column: str = "acceleration", *, time_column: str = "time", dt: float | None = None,
             scale: float = 1.0) -> GroundMotion:
    """Read a ground-acceleration record from a CSV file.

    Parameters
    ----------
    path : str or Path
    column : str
        Header name of the acceleration column.
    time_column : str
        Header name of the time column [s]; used if present (uniform spacing required).
    dt : float, optional
        Sampling step [s] if the file has no time column; if both are given they must agree.
    scale : float
        Factor to m/s^2 (``STANDARD_GRAVITY`` for a record in g).

    Returns
    -------
    GroundMotion
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such record file")
    rows = _rows(path)
    try:
        header_line, header = next(rows)
    except StopIteration:
        raise ValueError(f"{path}: no header line (only comments or blank lines)") from None
    if column not in header:
        raise ValueError(f"{path}, line {header_line}: no column {column!r}; columns are {header}")
    i_acc = header.index(column)
    i_time = header.index(time_column) if time_column in header else None
    if i_time is None and dt is None:
        raise ValueError(f"{path}: no column {time_column!r} and no dt given; columns are {header}")
    times, values = [], []
    for number, fields in rows:
        if len(fields) != len(header):
            raise ValueError(f"{path}, line {number}: {len(fields)} fields, the header has {len(header)}")
        values.append(_number(fields[i_acc], f"{path}, line {number}, column {column!r}"))
        if i_time is not None:
            times.append((number, _number(fields[i_time], f"{path}, line {number}, column {time_column!r}")))
    if len(values) < 2:
        raise ValueError(f"{path}: {len(values)} samples, a record needs at least 2")
    if i_time is not None:
        dt = _uniform_step(path, time_column, times, dt)
    return GroundMotion(float(dt), scale * np.array(values), name=str(path))


def _uniform_step(path: Path, time_column: str, times: list[tuple[int, float]], dt: float | None) -> float:
    """The step of uniformly spaced time stamps; raises naming the first line off the grid."""
    t = np.array([v for _, v in times])
    step = (t[-1] - t[0]) / (t.size - 1)
    if not step > 0:
        raise ValueError(f"{path}, column {time_column!r}: times must increase")
    off = np.abs(t - t[0] - step * np.arange(t.size)) > TIME_STEP_RTOL * step
    if np.any(off):
        number = times[int(np.argmax(off))][0]
        raise ValueError(f"{path}, line {number}, column {time_column!r}: time {t[np.argmax(off)]} s is off the uniform "
                         f"grid of step {step:.6g} s (records must be uniformly sampled)")
    if dt is not None and abs(dt - step) > TIME_STEP_RTOL * step:
        raise ValueError(f"{path}, column {time_column!r}: step {step:.6g} s disagrees with dt = {dt} s")
    return float(step)


def write_csv(record: GroundMotion, path, comments: tuple[str, ...] = ()) -> None:
    """Write ``record`` as ``time,acceleration`` [s, m/s^2] with ``#`` comment lines first."""
    lines = [f"# {c}" for c in comments] + ["time,acceleration"]
    lines += [f"{t:.{CSV_DIGITS}g},{a + 0.0:.{CSV_DIGITS}e}" for t, a in zip(record.t, record.acceleration)]
    Path(path).write_text("\n".join(lines) + "\n")


# ----------------------------------------------------------------------------------------------
# synthetic records
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class KanaiTajimi:
    """Kanai-Tajimi spectrum with the Clough-Penzien high-pass factor (shape of G; S0 set separately).

    Attributes
    ----------
    omega_g, zeta_g : float
        Ground filter frequency [rad/s] and damping; 15.6 rad/s and 0.6 are Tajimi's (1960) values
        for firm ground.
    omega_f, zeta_f : float
        High-pass filter frequency [rad/s] and damping (Clough & Penzien); 1.5 rad/s, 0.6.
    """

    omega_g: float = 15.6
    zeta_g: float = 0.6
    omega_f: float = 1.5
    zeta_f: float = 0.6

    def shape(self, omega) -> FloatArray:
        """G(omega) / S0, dimensionless, shape of omega."""
        r2 = (np.asarray(omega, float) / self.omega_g) ** 2
        rf2 = (np.asarray(omega, float) / self.omega_f) ** 2
        ground = (1.0 + 4.0 * self.zeta_g**2 * r2) / ((1.0 - r2) ** 2 + 4.0 * self.zeta_g**2 * r2)
        high_pass = rf2**2 / ((1.0 - rf2) ** 2 + 4.0 * self.zeta_f**2 * rf2)
        return ground * high_pass


@dataclass(frozen=True)
class Envelope:
    """Jennings-Housner-Tsai (1968) amplitude envelope: (t/rise)^2, then 1 until ``strong_end``, then
    exp(-decay (t - strong_end)). Times [s], decay [1/s]."""

    rise: float = 2.0
    strong_end: float = 10.0
    decay: float = 0.4

    def __call__(self, t) -> FloatArray:
        t = np.asarray(t, float)
        return np.where(t < self.rise, (t / self.rise) ** 2,
                        np.where(t <= self.strong_end, 1.0, np.exp(-self.decay * (t - self.strong_end))))


def stationary_signal(n: int, dt: float, spectrum: KanaiTajimi, seed: int, intensity: float = 1.0) -> FloatArray:
    """a_s(i dt), i < n: sum_k sqrt(2 S0 G(omega_k) d_omega) cos(omega_k t + theta_k) over 0 < omega_k < pi/dt.

    d_omega = 2 pi / (n dt); ``intensity`` is S0 [m^2/s^3]. Periodic with period n dt; its variance over
    one period is exactly sum_k S0 G(omega_k) d_omega (Parseval).
    """
    d_omega = 2.0 * np.pi / (n * dt)
    k = np.arange(1, (n + 1) // 2)  # strictly below the Nyquist frequency
    amplitude = np.sqrt(2.0 * intensity * spectrum.shape(k * d_omega) * d_omega)
    theta = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, k.size)
    half = np.zeros(n // 2 + 1, dtype=complex)
    half[k] = 0.5 * n * amplitude * np.exp(1j * theta)
    return np.fft.irfft(half, n)


def synthetic_record(duration: float = SHIPPED_DURATION, dt: float = SHIPPED_DT, *, pga: float | None = SHIPPED_PGA,
                     intensity: float = 1.0, spectrum: KanaiTajimi = KanaiTajimi(), envelope: Envelope = Envelope(),
                     seed: int = SHIPPED_SEED) -> GroundMotion:
    """A synthetic record: ``envelope(t) * stationary_signal(...)``, scaled to ``pga`` [m/s^2] if given
    (``intensity`` S0 [m^2/s^3] otherwise). Same seed, same record."""
    n = int(round(duration / dt)) + 1
    a = envelope(dt * np.arange(n)) * stationary_signal(n, dt, spectrum, seed, intensity)
    if pga is not None:
        a = a * (pga / np.abs(a).max())
    return GroundMotion(dt, a, name=f"synthetic Kanai-Tajimi record, seed {seed}")


def shipped_record() -> GroundMotion:
    """The record shipped in ``viz3d/hydro/data`` (see ``write_shipped_record`` for its recipe)."""
    return read_csv(SHIPPED_RECORD)


def write_shipped_record(path=SHIPPED_RECORD) -> GroundMotion:
    """(Re)generate the shipped record: ``synthetic_record()`` with the defaults stated in its header."""
    spectrum, envelope = KanaiTajimi(), Envelope()
    record = synthetic_record()
    write_csv(record, path, comments=(
        "viz3d synthetic horizontal ground acceleration [m/s^2] (viz3d.hydro.records.write_shipped_record)",
        f"spectral representation, seed {SHIPPED_SEED}, duration {SHIPPED_DURATION} s, dt {SHIPPED_DT} s, "
        f"scaled to PGA {SHIPPED_PGA:.6g} m/s^2 (0.3 g)",
        f"Kanai-Tajimi omega_g {spectrum.omega_g} rad/s, zeta_g {spectrum.zeta_g}; Clough-Penzien omega_f "
        f"{spectrum.omega_f} rad/s, zeta_f {spectrum.zeta_f}",
        f"Jennings-Housner-Tsai envelope: rise {envelope.rise} s, strong phase to {envelope.strong_end} s, "
        f"decay {envelope.decay} 1/s",
        "regenerate: python -c 'from viz3d.hydro.records import write_shipped_record; write_shipped_record()'",
    ))
    return record
