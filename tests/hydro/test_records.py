"""Ground-motion records: the CSV reader's errors, the synthetic record's spectrum, the shipped file."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from viz3d.hydro import records as Rec

EPS = np.finfo(float).eps


def write(tmp_path, text, name="record.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


# ----------------------------------------------------------------------------------------------
# CSV
# ----------------------------------------------------------------------------------------------
def test_reads_time_and_acceleration_skipping_comments(tmp_path):
    path = write(tmp_path, "# a comment\n\ntime,acc_g\n0.0,0.1\n0.01,-0.2\n0.02,0.05\n")
    record = Rec.read_csv(path, "acc_g", scale=Rec.STANDARD_GRAVITY)
    assert record.dt == pytest.approx(0.01, rel=1e-12)
    assert np.array_equal(record.acceleration, Rec.STANDARD_GRAVITY * np.array([0.1, -0.2, 0.05]))


def test_round_trip_through_write_csv(tmp_path):
    record = Rec.synthetic_record(duration=2.0, dt=0.01, seed=1)
    Rec.write_csv(record, tmp_path / "out.csv", comments=("made by a test",))
    back = Rec.read_csv(tmp_path / "out.csv")
    assert back.dt == pytest.approx(record.dt, rel=1e-9)
    digits = 0.5 * 10.0 ** -(Rec.CSV_DIGITS)  # relative rounding of "%.{CSV_DIGITS}e"
    assert np.all(np.abs(back.acceleration - record.acceleration) <= digits * np.abs(record.acceleration) + 1e-300)


@pytest.mark.parametrize("text, kwargs, message", [
    ("time,acc\n0,1\n0.01,2\n", {}, r"record\.csv, line 1: no column 'acceleration'; columns are \['time', 'acc'\]"),
    ("time,acceleration\n0,1\n0.01,abc\n", {}, r"record\.csv, line 3, column 'acceleration': 'abc' is not a number"),
    ("time,acceleration\n0,1\n0.01\n", {}, r"record\.csv, line 3: 1 fields, the header has 2"),
    ("time,acceleration\n0,1\n0.01,2\n0.025,3\n0.03,4\n", {}, r"record\.csv, line 4, column 'time': .* off the uniform"),
    ("acceleration\n1\n2\n", {}, r"record\.csv: no column 'time' and no dt"),
    ("time,acceleration\n0,1\n", {}, r"record\.csv: 1 samples"),
    ("# only a comment\n", {}, r"record\.csv: no header"),
    ("time,acceleration\n0,1\n0.01,2\n", {"dt": 0.02}, r"record\.csv, column 'time': step 0\.01 s disagrees"),
    ("time,acceleration\n0,1\n0.01,nan\n", {}, r"line 3, column 'acceleration': 'nan' is not finite"),
])
def test_csv_errors_name_file_line_and_column(tmp_path, text, kwargs, message):
    with pytest.raises(ValueError, match=message):
        Rec.read_csv(write(tmp_path, text), **kwargs)


def test_missing_file_is_named(tmp_path):
    with pytest.raises(FileNotFoundError, match="nowhere.csv"):
        Rec.read_csv(tmp_path / "nowhere.csv")


def test_dt_without_time_column(tmp_path):
    record = Rec.read_csv(write(tmp_path, "acceleration\n1\n2\n3\n"), dt=0.005)
    assert record.dt == 0.005 and record.acceleration.size == 3


# ----------------------------------------------------------------------------------------------
# the synthetic record
# ----------------------------------------------------------------------------------------------
def test_stationary_signal_has_the_stated_fourier_amplitudes():
    """Each DFT bin k carries (n/2) sqrt(2 S0 G(omega_k) d_omega): the stated spectrum, exactly up to
    the FFT's rounding (~ eps log2 n of the largest amplitude)."""
    n, dt, S0 = 4000, 0.01, 0.37
    spectrum = Rec.KanaiTajimi()
    a = Rec.stationary_signal(n, dt, spectrum, seed=5, intensity=S0)
    d_omega = 2 * np.pi / (n * dt)
    k = np.arange(1, n // 2)
    target = 0.5 * n * np.sqrt(2 * S0 * spectrum.shape(k * d_omega) * d_omega)
    assert np.abs(np.abs(np.fft.rfft(a)[k]) - target).max() <= 100 * EPS * np.log2(n) * target.max()


def test_stationary_variance_is_the_area_under_the_spectrum():
    """Parseval: the variance over the period is sum_k S0 G(omega_k) d_omega. That right-endpoint
    Riemann sum over [0, K d_omega] differs from the integral by at most d_omega TV(G), and the cell
    [K d_omega, omega_N] it leaves out holds at most d_omega max G <= d_omega TV(G) (G(0) = 0):
    |sum - int_0^omega_N G| <= 2 d_omega TV(G), plus quad's own error estimate."""
    n, dt = 4000, 0.01
    spectrum = Rec.KanaiTajimi()
    a = Rec.stationary_signal(n, dt, spectrum, seed=11)
    d_omega = 2 * np.pi / (n * dt)
    k = np.arange(1, (n + 1) // 2)
    riemann = (spectrum.shape(k * d_omega) * d_omega).sum()
    assert abs(np.mean(a**2) - riemann) <= 1e3 * EPS * riemann  # Parseval: exact
    omega_n = np.pi / dt
    area, error = quad(spectrum.shape, 0.0, omega_n, limit=200)
    grid = np.linspace(0.0, omega_n, 200_001)
    variation = np.abs(np.diff(spectrum.shape(grid))).sum()
    assert abs(riemann - area) <= 2 * d_omega * variation + error


def test_same_seed_same_record_and_pga_as_stated():
    a, b = Rec.synthetic_record(seed=3), Rec.synthetic_record(seed=3)
    assert np.array_equal(a.acceleration, b.acceleration)
    assert not np.array_equal(a.acceleration, Rec.synthetic_record(seed=4).acceleration)
    assert a.pga == pytest.approx(Rec.SHIPPED_PGA, rel=4 * EPS)
    assert a.acceleration[0] == 0.0  # the envelope starts from rest


def test_shipped_record_is_reproducible_from_its_stated_recipe():
    shipped = Rec.shipped_record()
    remade = Rec.synthetic_record()
    assert shipped.dt == pytest.approx(Rec.SHIPPED_DT, rel=1e-9)
    digits = 0.5 * 10.0 ** -(Rec.CSV_DIGITS)
    assert np.all(np.abs(shipped.acceleration - remade.acceleration) <= digits * np.abs(remade.acceleration) + 1e-300)
    text = Rec.SHIPPED_RECORD.read_text()
    assert f"seed {Rec.SHIPPED_SEED}" in text and "omega_g 15.6 rad/s" in text
