"""Dam-reservoir hydrodynamics: Chopra's (1967) pressure series, the fluid's dynamic stiffness, and a
flexible dam coupled to it (seed 000, chapter 4; issue 13).

Conventions (docs/hydro.md derives everything and lists the seed's errata; units SI as in
docs/notation.md):

* **Geometry.** Reservoir x >= 0 (upstream from the dam face), 0 <= y <= h (up from the bottom).
  Wall motion, ground motion and dam deflection are positive towards the reservoir (+x).
* **Time.** Harmonic quantities are complex amplitudes of exp(j omega t); a propagating term is
  exp(j (omega t - k x)) with k of the sign of omega (causal limit), so S(-omega) = conj S(omega).
* **Pressure** p is hydrodynamic (static pressure excluded), positive in compression, per unit
  amplitude of wall *acceleration* [Pa / (m/s^2) = kg/m^2].
* **Added mass** A_ij = int_0^h phi_i p_j dy and **dynamic stiffness** S = -omega^2 A, per metre of
  dam width: S q is the force the wall exerts on the water for the wall displacement
  sum_j phi_j q_j. Re S < 0: added mass; Im S > 0 (omega > 0): power leaving the dam,
  (omega / 2) q^H Im(S) q.
* **Truncation.** Every series is summed to a number of terms chosen from ``rtol`` (relative to
  rho h max|phi| for pressures, rho h^2 max|phi_i| max|phi_j| for A) with an a-priori bound; the
  result carries both (``SeriesResult.n_terms``, ``.bound``).

Modules: ``shapes`` (wall shapes and their modal moments), ``reservoir`` (pressure, added mass,
dynamic stiffness, bottom absorption), ``dam`` (cantilever dam from ``viz3d.flexible``, crest
frequency and time response), ``records`` (ground-motion CSV reader, synthetic Kanai-Tajimi
records, the shipped record).
"""

from viz3d.hydro.dam import (
    Dam,
    FrequencyResponse,
    TimeResponse,
    cantilever_dam,
    frequency_response,
    fundamental_frequency,
    time_response,
)
from viz3d.hydro.records import GroundMotion, KanaiTajimi, read_csv, shipped_record, synthetic_record
from viz3d.hydro.reservoir import (
    SEED_EXAMPLE,
    Reservoir,
    SeriesResult,
    added_mass,
    dynamic_stiffness,
    pressure,
    westergaard_pressure,
)
from viz3d.hydro.shapes import SampledShapes, SmoothShapes, uniform

__all__ = [
    "Dam", "FrequencyResponse", "TimeResponse", "cantilever_dam", "frequency_response", "fundamental_frequency",
    "time_response",
    "GroundMotion", "KanaiTajimi", "read_csv", "shipped_record", "synthetic_record",
    "SEED_EXAMPLE", "Reservoir", "SeriesResult", "added_mass", "dynamic_stiffness", "pressure", "westergaard_pressure",
    "SampledShapes", "SmoothShapes", "uniform",
]
