"""Compiled fast path (numba) of the vector field and of explicit Runge-Kutta stepping.

The NumPy implementation (``viz3d.dynamics`` and the elements) is the reference; the kernel computes
the same quantities with compiled loops, because for small systems NumPy's per-call overhead
dominates. It is composed, not copied: the generic parts (bodies' kinematics and mass blocks, rigid
or flexible; the constraint assembly and banded solve; the RK loop) live here and in
``viz3d.flexible.floating_kernel``, and each element type adds its compiled piece next to its NumPy
code (``viz3d.compiled``). Every orientation coordinate set of ``viz3d.coordinates`` is covered:
ZXZ Euler angles, plain or re-charted, and Euler parameters (normalised between steps).
``kernel_coverage`` says why a system is not covered (an element without a compiled piece, a
formulation the kernel lacks); such a run takes the NumPy path and reports it.
tests/numerics/test_kernel_elements.py compares the two on a random system holding every registered
element type.

Modules: ``model`` (packing), ``field`` (the vector field), ``stepping`` (RK steps), ``adaptive``
(adaptive runs: error control, dense output, event sign checks, step records of law contacts), ``projection``
(the ``projection`` formulation's post-step projections), ``sampling`` (output samples), ``ali3p`` (ALI3-P's
steps and runs of them, compiled: ``viz3d.ali3p``'s compiled path), ``collisions`` (the shape contacts'
piece and their stick anchors, packed through ``Packer.collision_items``: ``viz3d.contact`` is a layer below).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from viz3d.compiled import numba
from viz3d.contact.contacts import MEMORY_COLUMNS, memory_rows

try:  # numba's fingerprint of an argument's type (C, fast), the key of its own dispatch cache
    from numba._dispatcher import compute_fingerprint
except ImportError:  # pragma: no cover - no numba, or a numba without it: _entry_point types each time
    pass
from viz3d.kernel.field import NONFINITE, OK, PROJECTION, ROTATION, SINGULAR, SPEED, gaps, rhs
from viz3d.kernel.model import KernelData, Unsupported, pack, per_run, workspace
from viz3d.kernel.stepping import advance_frames, rk_step, state_ok

__all__ = ["OK", "NONFINITE", "SINGULAR", "SPEED", "ROTATION", "PROJECTION", "EVENT", "UNDERFLOW", "FULL", "UNLOCATED",
           "KernelData", "kernel_for", "kernel_coverage", "keep_packed", "type_prints", "kernel_rhs", "kernel_advance",
           "CompiledField", "KernelStepper",
           "AdaptiveCarry", "StepRecords"]


#: Names of the compiled adaptive driver (``viz3d.kernel.adaptive``) given here too, imported on first
#: use: a run with fixed steps does not import the driver (7 ms of its start).
_ADAPTIVE_NAMES = ("EVENT", "FULL", "UNDERFLOW", "UNLOCATED")


def __getattr__(name: str):
    if name in _ADAPTIVE_NAMES:
        from viz3d.kernel import adaptive

        return getattr(adaptive, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def kernel_coverage(system, formulation) -> tuple[KernelData | None, str | None]:
    """``(data, None)`` when the kernel covers ``system`` with ``formulation``, else ``(None, why)``.

    Packed once per system and formulation (``formulation``'s value: its class and parameters) and
    kept with the system (``System.derived``), so that its runs share it (``keep_packed``), unless
    a run writes to it (``model.per_run``): then packed anew for each caller."""
    if numba is None:
        return None, "numba is not installed"
    if per_run(system, formulation):
        return _coverage(system, formulation)
    key = ("kernel", formulation)
    kept = system.derived.get(key)
    if kept is None:
        kept = system.derived[key] = _coverage(system, formulation)
    return kept


def _coverage(system, formulation) -> tuple[KernelData | None, str | None]:
    """``kernel_coverage``, packed now."""
    try:
        return pack(system, formulation), None
    except Unsupported as e:
        return None, str(e)


def keep_packed(system, formulation) -> None:
    """Pack ``system`` for ``formulation`` now, kept with it for its runs (``kernel_coverage``), when
    they can share it, with the fingerprints of its tuples (``type_prints``): what
    ``viz3d.scene.build.build`` does with the model it builds, as the run's clock starts once the
    model is built."""
    if numba is not None and not per_run(system, formulation):
        data = kernel_coverage(system, formulation)[0]
        if data is not None:
            type_prints(data)


#: The ``KernelData`` fields the compiled calls take (tuples of arrays; ``memories`` may be None).
DATA_TUPLES = ("model", "forces", "rows", "geometry", "energies", "memories", "replants")


def type_prints(data: KernelData) -> dict:
    """numba's fingerprints (``_entry_point``) of ``data``'s tuples (``DATA_TUPLES``), by field name,
    computed once per packed data and kept in ``data.prints`` (about 16 us of the first compiled call
    of each run otherwise); none where numba's fingerprint is unavailable."""
    if not data.prints:
        try:
            data.prints.update({name: compute_fingerprint(getattr(data, name)) for name in DATA_TUPLES
                                if getattr(data, name) is not None})
        except (NameError, TypeError, ValueError, NotImplementedError):  # (_entry_point then types them itself)
            data.prints.clear()
    return data.prints


def kernel_for(system, formulation) -> KernelData | None:
    """Packed data when the kernel covers ``system`` with ``formulation``, else None."""
    return kernel_coverage(system, formulation)[0]


def memory_table(data: KernelData, memory: tuple) -> np.ndarray:
    """The contacts' memory rows (``viz3d.contact.contacts.memory_rows``) of all sets, (n_contacts, 7)."""
    if not memory:
        return np.zeros((data.n_contacts, MEMORY_COLUMNS))
    return (np.concatenate([memory_rows(phases) for phases in memory]) if data.n_contacts
            else np.zeros((0, MEMORY_COLUMNS)))


def load_elements(data: KernelData, elements: tuple) -> None:
    """Put the force elements' memory ``elements`` (a ``State.element_memory``; () at none) into their
    packed data: the stick anchors of shape contacts (``viz3d.kernel.collisions.load_anchors``)."""
    if not data.anchors:
        return
    from viz3d.kernel.collisions import load_anchors  # (imported by the packing of ``data.anchors``)

    for k, d in data.anchors:
        load_anchors(d, elements[k] if elements else None)


def stored_elements(data: KernelData, like: tuple) -> tuple:
    """``like`` (a ``State.element_memory``) with the memory now in the packed data (after compiled steps)."""
    if not data.anchors:
        return like
    from viz3d.kernel.collisions import stored_anchors
    out = list(like)
    for k, d in data.anchors:
        out[k] = stored_anchors(d)
    return tuple(out)


def kernel_rhs(data: KernelData, t: float, y: np.ndarray, chart: np.ndarray, memory: tuple = (),
               elements: tuple = ()) -> np.ndarray:
    """The compiled right-hand side (for tests and diagnostics), with the contacts' memory ``memory``
    and the force elements' ``elements``."""
    load_elements(data, elements)
    v, w = workspace(data)
    v = v._replace(mem=memory_table(data, memory))
    out = np.empty_like(y)
    if rhs(t, y, chart, data.model, v, w, data.forces, data.rows, out) != OK:
        raise np.linalg.LinAlgError("mass block or constraint matrix is not positive definite")
    return out


class CompiledField:
    """A ``dynamics.VectorField`` whose evaluations run in the kernel (same interface); the contact
    memory is the field's own (its ``memory``)."""

    def __init__(self, field, stepper: "KernelStepper"):
        self.field, self.stepper = field, stepper
        self.n_q, self.n_v, self.chart, self.dexpinv = field.n_q, field.n_v, field.chart, field.dexpinv
        self.v = stepper.view(field.memory)

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        self.field.n_evals += 1
        self.stepper.load(self.field.elements)
        y = _c(y)
        out = np.empty_like(y)
        if self.stepper.evaluate(t, y, self.chart, self.v, out) != OK:
            return self.field(t, y)  # the NumPy path raises the detailed error
        return out

    def retract(self, q, w):
        return self.field.retract(q, w)

    def rk_step(self, tableau, t: float, y: np.ndarray, h: float, f0: np.ndarray | None):
        """One explicit Runge-Kutta step of ``tableau`` in the kernel: ``(y1, error, stages)``
        (error None without an embedded solution), or None when an evaluation fails (the caller
        then takes the NumPy path, which raises the detailed error)."""
        st = self.stepper
        st.load(self.field.elements)
        y, f0 = _c(y), (None if f0 is None else _c(f0))
        n, s = y.shape[0], len(tableau.b)
        k, y1, err = np.empty((s, n)), np.empty(n), np.empty(n)
        use_f0 = f0 is not None
        d = st.data
        status = st._call(rk_step, t, h, y, _c(self.chart), f0 if use_f0 else y, use_f0, tableau.a, tableau.b,
                          tableau.error_weights, tableau.c, int(not tableau.embedded), d.model, self.v, st.ws[1], d.forces,
                          d.rows, k, st._yi, y1, err)
        self.field.n_evals += s - use_f0
        if status != OK:
            return None
        return y1, (err if tableau.embedded else None), k


class AdaptiveCarry(NamedTuple):
    """What an adaptive run carries from one compiled call to the next (``viz3d.kernel.adaptive``,
    whose module docstring describes each field; updated in place).

    y, f, y0, f1, y_cut : (n,)
    chart, chart0 : (nf, 3, 3)
    times : (5,) [s]
    flags : (4,) int64
    counts : (3,) int64
    switches : (nb,) int64
        Chart switches per body during the calls.
    K : (s + m, n)
    Q : (degree, n)
    """

    y: np.ndarray
    chart: np.ndarray
    f: np.ndarray
    times: np.ndarray
    flags: np.ndarray
    counts: np.ndarray
    switches: np.ndarray
    y0: np.ndarray
    chart0: np.ndarray
    K: np.ndarray
    Q: np.ndarray
    f1: np.ndarray
    y_cut: np.ndarray

    @classmethod
    def empty(cls, n: int, n_frames: int, n_bodies: int, tableau) -> "AdaptiveCarry":
        """A carry for states of ``n`` entries and ``tableau``'s stages (and extra dense stages)."""
        z = np.zeros
        dense = tableau.dense  # (None: fixed steps, which land on the samples)
        extra, degree = (0, 0) if dense is None else (len(dense.c_extra), dense.P.shape[1])
        return cls(z(n), z((n_frames, 3, 3)), z(n), z(5), z(4, np.int64), z(3, np.int64), z(n_bodies, np.int64),
                   z(n), z((n_frames, 3, 3)), z((len(tableau.b) + extra, n)), z((degree, n)), z(n), z(n))

    def copy(self) -> "AdaptiveCarry":
        return AdaptiveCarry(*(a.copy() for a in self))


class StepRecords(NamedTuple):
    """The accepted steps of an adaptive call while a law contact acts (``viz3d.kernel.adaptive``'s
    step records), for the contacts' bookkeeping in Python; ``n[0]`` of the ``capacity`` rows used.

    t : (R,) [s]
        End time of each step.
    y, err : (R, n)
        The settled state at its end and the step's error estimate.
    chart : (R, nf, 3, 3)
    mem : (R, n_contacts, 7)
        The contacts' memory rows after it (``viz3d.contact.contacts.memory_rows``: the stick anchors
        the driver moved).
    n : (1,) int64
    """

    t: np.ndarray
    y: np.ndarray
    chart: np.ndarray
    err: np.ndarray
    mem: np.ndarray
    n: np.ndarray

    @classmethod
    def empty(cls, capacity: int, n: int, n_frames: int, n_contacts: int) -> "StepRecords":
        z = np.zeros
        return cls(z(capacity), z((capacity, n)), z((capacity, n_frames, 3, 3)), z((capacity, n)),
                   z((capacity, n_contacts, MEMORY_COLUMNS)), z(1, np.int64))

    @property
    def capacity(self) -> int:
        return self.t.shape[0]


class Samples(NamedTuple):
    """Output samples of N states (``KernelStepper.sample``; nb + 1 bodies, ground last).

    r, vW, wW, wB : (N, nb + 1, 3)
        Frame origins [m], their velocities [m/s], angular velocities in world and body axes [rad/s].
    R : (N, nb + 1, 3, 3)
        Rotations body -> world.
    eta, eta_dot : (N, n_e)
        Elastic coordinates and rates.
    lam, C : (N, n_c)
        Multipliers and residuals of the constraint rows; J (N, n_c, 2, 6) their frame Jacobian blocks.
    gap : (N, k, 11)
        Every contact's gap (``KernelStepper.gaps``).
    T : (N,)
        Kinetic energy of the rigid bodies [J].
    V : (N, 2)
        Potential energy of the force elements: the part that may be negative, the rest [J].
    """

    r: np.ndarray
    R: np.ndarray
    vW: np.ndarray
    wW: np.ndarray
    wB: np.ndarray
    eta: np.ndarray
    eta_dot: np.ndarray
    lam: np.ndarray
    C: np.ndarray
    J: np.ndarray
    gap: np.ndarray
    T: np.ndarray
    V: np.ndarray


def _c(a: np.ndarray) -> np.ndarray:
    """``a`` as the compiled entries were compiled for: C-contiguous float64 (copied only when it is
    not). ``KernelStepper`` reuses the entry of the first call's argument types, which would read an
    array of another layout or dtype wrongly."""
    return a if a.dtype == np.float64 and a.flags.c_contiguous else np.ascontiguousarray(a, dtype=np.float64)


#: Compiled entries found by ``_entry_point``, keyed by dispatcher and the arguments' fingerprints.
_ENTRIES: dict = {}


def _entry_point(dispatcher, args, fingerprint=None, accepted: bool = False):
    """The compiled entry of ``dispatcher`` for these argument types (skips the per-call type
    dispatch, a few microseconds for tuples of arrays); the dispatcher itself if unavailable.

    Looked up once per process and argument types: numba's own typing of the arguments (``typeof``)
    costs about a millisecond for the packed model's tuples of arrays, 6 of a small run's 8 ms
    before this cache. The key is numba's fingerprint of each argument (``fingerprint(a)``, numba's
    ``compute_fingerprint`` unless given), the key numba's dispatcher caches its own typing under
    (so equal fingerprints mean equal types). ``accepted``: ``dispatcher`` has just been called with
    ``args`` (``_typed_entry``)."""
    try:
        key = (dispatcher, tuple(map(fingerprint or compute_fingerprint, args)))
    except (NameError, TypeError, ValueError, NotImplementedError):  # no fingerprint: type them each time
        return _typed_entry(dispatcher, args)
    entry = _ENTRIES.get(key)
    if entry is None:
        entry = _typed_entry(dispatcher, args, accepted)
        if entry is not dispatcher:  # (not compiled nor loaded in this process yet: look again after a call)
            _ENTRIES[key] = entry
    return entry


def _typed_entry(dispatcher, args, accepted: bool = False):
    """``_entry_point`` by the typing of ``args`` (``_argument_type``), the entry loaded from numba's
    cache (or compiled) for them where the dispatcher holds none yet: a call of the dispatcher itself
    would type them with numba's ``typeof``, which imports ``numpy.ma`` to ask whether an array is
    masked (10 ms of a run's start). Without typing where it holds one signature and has ``accepted``
    these arguments (then that one is theirs); the typing takes about 2 ms for the packed model.
    The dispatcher itself where no entry can be had so (no numba)."""
    overloads = getattr(dispatcher, "overloads", None)
    if overloads is None:
        return dispatcher
    if accepted and len(overloads) == 1:
        return next(iter(overloads.values())).entry_point
    try:
        sig = tuple(_argument_type(dispatcher, a) for a in args)
        if sig not in overloads:
            dispatcher.compile(sig)
        return overloads[sig].entry_point
    except (AttributeError, KeyError):
        return dispatcher


def _argument_type(dispatcher, a):
    """numba's type of the argument ``a``, as ``dispatcher``'s typing of a call gives it
    (``numba.core.typing.typeof``: arrays by dtype, dimensions, layout and writability, tuples and
    named tuples by their items, through numba's own constructors), without asking whether an array
    is masked (``type(a) is np.ndarray``; any other value is typed by numba)."""
    from numba.core import types
    from numba.np import numpy_support

    if type(a) is np.ndarray:
        return types.Array(numpy_support.from_dtype(a.dtype), a.ndim, numpy_support.map_layout(a),
                           readonly=not a.flags.writeable)
    if type(a) is tuple or (isinstance(a, tuple) and hasattr(type(a), "_asdict")):
        return types.BaseTuple.from_types([_argument_type(dispatcher, x) for x in a], type(a))
    return dispatcher.typeof_pyval(a)


class KernelStepper:
    """One run of a system in the kernel: its packed data (shared by the system's runs), its own
    workspace and explicit RK steps; the compiled entries are looked up once per packed data
    (``KernelData.entries``)."""

    def __init__(self, data: KernelData, tableau):
        self.data, self.tableau = data, tableau
        self.ws = workspace(data)
        #: The fingerprints (``_entry_point``) of the packed data's tuples (``type_prints``) and of the
        #: workspace's (None until first needed), by ``id``: the same objects in each entry's first call.
        self._prints: dict = {id(x): None for x in self.ws}
        self._prints.update({id(getattr(data, name)): p for name, p in type_prints(data).items()})
        self._memory_id, self._view = None, self.ws[0]
        self._elements_id = None  # the force elements' memory in the packed data (None: unknown)
        self._method = None  # the tableau and controller as the adaptive driver takes them
        n = data.model.n_q + data.model.n_v + data.model.n_aux
        stages = 0 if tableau is None else len(tableau.b)  # None: evaluations only (CompiledField)
        self._k, self._yi = np.empty((stages, n)), np.empty(n)
        self._one = None  # ``step``'s buffers of one frame (``advance_frames``'s Y, charts, ts, samples)

    def view(self, memory: tuple):
        """The workspace's view with the contacts' memory ``memory`` (a ``State.memory``)."""
        if memory is not self._memory_id:
            self._memory_id, self._view = memory, self.ws[0]._replace(mem=memory_table(self.data, memory))
        return self._view

    def load(self, elements: tuple) -> None:
        """Put the force elements' memory ``elements`` (a ``State.element_memory``) into the packed data,
        unless it is there (by identity)."""
        if self.data.anchors and elements is not self._elements_id:
            load_elements(self.data, elements)
            self._elements_id = elements

    def stored(self, like: tuple) -> tuple:
        """The force elements' memory after the last compiled steps (``stored_elements``)."""
        return stored_elements(self.data, like)

    def _call(self, dispatcher, *args):
        """``dispatcher(*args)`` through its compiled entry for these argument types: found once per
        packed data (``_entry_point``, once per process; the arguments of a call site have the same
        types for every stepper of the data: its tuples, a workspace of its sizes, C-contiguous
        float64 tableaus), the dispatcher itself only on the process's first call (which compiles
        or loads the entry)."""
        entries = self.data.entries
        fn = entries.get(dispatcher)
        if fn is None:
            fn = _entry_point(dispatcher, args, self._fingerprint)
            if fn is dispatcher:
                result = dispatcher(*args)
                entries[dispatcher] = _entry_point(dispatcher, args, self._fingerprint, accepted=True)
                return result
            entries[dispatcher] = fn
        return fn(*args)

    def _fingerprint(self, a) -> object:
        """numba's fingerprint of the argument ``a``, computed once for the packed data's and this
        stepper's own tuples."""
        known = self._prints.get(id(a))
        if known is not None:
            return known
        p = compute_fingerprint(a)
        if id(a) in self._prints:
            self._prints[id(a)] = p
        return p

    def evaluate(self, t: float, y: np.ndarray, chart: np.ndarray, v, out: np.ndarray) -> int:
        """``out = f(t, y)`` with the view ``v`` (``view``); returns the status."""
        d = self.data
        return self._call(rhs, t, _c(y), _c(chart), d.model, v, self.ws[1], d.forces, d.rows, out)

    def multipliers(self, t: float, y: np.ndarray, chart: np.ndarray, memory: tuple, elements: tuple = ()) -> np.ndarray:
        """The constraint multipliers at ``(t, y)`` (n_c,) (those of kinematic contacts included), with the
        force elements' memory ``elements``."""
        self.load(elements)
        out = np.empty_like(y)
        if self.evaluate(t, y, chart, self.view(memory), out) != OK:
            raise np.linalg.LinAlgError("mass block or constraint matrix is not positive definite")
        return self.ws[1].lam.copy()

    def project(self, t: float, y: np.ndarray, chart: np.ndarray, memory: tuple) -> tuple[np.ndarray, bool]:
        """``(y', ok)``: ``y`` projected onto the constraints at ``t`` [s] (``viz3d.kernel.projection``,
        the ``projection`` formulation's ``post_step``), a new array; ``ok`` False when the projection
        failed (the NumPy path then raises its diagnosis)."""
        out = np.array(y, dtype=np.float64)  # a C-contiguous copy, projected in place
        chart = _c(chart)
        status = self._frames_call(0, -1, 0, t, 0.0, out, chart, np.zeros(0, np.int64), 0.0,
                                   np.empty((0, out.shape[0])), np.empty((0, *chart.shape)), np.empty(0),
                                   np.zeros(1, np.int64), self._samples(0), self.view(memory))[2]
        return out, status == OK

    def state_ok(self, y: np.ndarray, h: float, max_speed: float) -> bool:
        """True when ``viz3d.diagnosis.check_state`` passes ``y`` after a step ``h`` (compiled);
        False means: run that check for its diagnosis."""
        m = self.data.model
        return bool(self._call(state_ok, m.n_q, m.n_v, m.n_rot, m.switching, m.frame_body.shape[0], _c(y), h,
                               max_speed))

    def solved_rows(self, t: float, y: np.ndarray, chart: np.ndarray, memory: tuple, elements: tuple = ()) -> tuple:
        """``(lam, C, J)`` at ``(t, y)``: the multipliers (n_c,), residuals (n_c,) and frame Jacobian
        blocks (n_c, 2, 6) of every constraint row (``viz3d.constraints.ConstraintRows``' C and J)."""
        lam = self.multipliers(t, y, chart, memory, elements)
        return lam, self.ws[0].C.copy(), self.ws[0].J.copy()

    def gaps(self, t: float, y: np.ndarray, chart: np.ndarray) -> np.ndarray:
        """Every contact's gap, (n_contacts, 11): ``alpha`` [m], ``alpha_dot`` [m/s], world normal,
        ``a - b`` [m] and contact point [m] (``viz3d.contact.contacts.Gap``, columns 2-4, 5-7, 8-10)."""
        d = self.data
        out = np.empty((d.n_contacts, 11))
        self._call(gaps, t, _c(y), _c(chart), d.model, self.ws[0], self.ws[1], d.geometry, out)
        return out

    def configuration(self, t: float, y: np.ndarray, chart: np.ndarray) -> tuple:
        """``(Configuration, gaps)`` at ``(t, y)``: what ``viz3d.dynamics.body_state`` and each contact
        set's ``gap`` compute, from one compiled call (for output frames)."""
        from viz3d.contact.contacts import Gap
        from viz3d.kinematics import Configuration, Pose, Twist

        g = self.gaps(t, y, chart)
        v, w = self.ws
        eta = tuple(w.eta[sl].copy() for sl in self.data.elastic_slices)
        eta_dot = tuple(w.eta_dot[sl].copy() for sl in self.data.elastic_slices)
        cfg = Configuration(t, Pose(w.r.copy(), v.R.copy()), Twist(w.vW.copy(), w.wB.copy(), v.wW.copy()), eta,
                            eta_dot)
        return cfg, tuple(Gap(g[sl, 0], g[sl, 1], g[sl, 2:5], g[sl, 5:8], g[sl, 8:11]) for sl in self.data.contact_slices)

    def sample(self, ts: np.ndarray, Y: np.ndarray, charts: np.ndarray, memory: tuple, elements: tuple = ()) -> "Samples":
        """What output frames need at the states ``(ts[i], Y[i], charts[i])`` (N,), (N, n_y),
        (N, nf, 3, 3), all with the contacts' memory ``memory`` and the force elements' ``elements``,
        from one compiled call (see ``Samples``); raises ``LinAlgError`` naming the first state whose
        evaluation fails."""
        self.load(elements)
        n = ts.shape[0]
        out = self._samples(n)
        if n == 0:
            return out
        Y, charts = _c(Y), _c(charts)
        done, _, _ = self._frames_call(n, 0, 0, 0.0, 0.0, Y[0], charts[0],
                                       np.zeros(0, np.int64), 0.0, Y, charts, _c(ts), np.zeros(1, np.int64), out,
                                       self.view(memory))
        if done < n:
            raise np.linalg.LinAlgError(f"t = {ts[done]:.6g} s: mass block or constraint matrix is not positive definite")
        return out

    def _samples(self, n: int) -> "Samples":
        """Uninitialised ``Samples`` of ``n`` states."""
        d, m = self.data, self.data.model
        nb1, n_c = m.nb + 1, self.ws[0].C.shape[0]
        z = np.empty
        return Samples(z((n, nb1, 3)), z((n, nb1, 3, 3)), z((n, nb1, 3)), z((n, nb1, 3)), z((n, nb1, 3)),
                       z((n, m.n_e)), z((n, m.n_e)), z((n, n_c)), z((n, n_c)), z((n, n_c, 2, 6)),
                       z((n, d.n_contacts, 11)), z(n), z((n, 2)))

    def step(self, t: float, h: float, y: np.ndarray, chart: np.ndarray, switches: np.ndarray,
             max_speed: float, n_steps: int = 1, elements: tuple = ()) -> tuple[int, int]:
        """``n_steps`` steps of ``y``, ``chart`` in place from the force elements' memory ``elements``
        (renewed after each step: ``stored`` gives it afterwards); returns (steps done, status code,
        ``OK`` = 0). On a failure ``y`` holds the failed step's result."""
        if _c(y) is not y or _c(chart) is not chart:
            raise ValueError("the kernel steps y and chart in place: they must be C-contiguous float64 arrays")
        self._fresh(elements)
        if n_steps <= 0:  # (advance_frames' every = 0 samples given states instead)
            return 0, OK
        if self._one is None:  # (one frame's buffers, nothing sampled: advance_frames as the plain steps)
            self._one = (np.empty((1, y.shape[0])), np.empty((1, *chart.shape)), np.empty(1), self._samples(0))
        Y, charts, ts, out = self._one
        _, done, status = self._frames_call(1, n_steps, 0, t, h, y, chart, switches, max_speed, Y, charts, ts,
                                            np.zeros(1, np.int64), out, self.ws[0])
        return done, status

    def _fresh(self, elements: tuple) -> None:
        """``elements`` loaded for steps that renew it in place (the packed data's memory is then
        unknown to ``load``)."""
        self._elements_id = None
        self.load(elements)
        self._elements_id = None


    def frames(self, n_frames: int, every: int, n0: int, t0: float, h: float, y: np.ndarray, chart: np.ndarray,
               switches: np.ndarray, max_speed: float, elements: tuple = (), sampling: bool = False
               ) -> tuple[np.ndarray, np.ndarray, int, int, int, "Samples | None"]:
        """``n_frames`` times ``every`` steps of ``y``, ``chart`` in place, from step ``n0`` of a run
        started at ``t0`` [s] and the force elements' memory ``elements`` (``stored`` gives it after
        the last frame): ``(Y, charts, frames done, steps done in the next frame, status, samples)``,
        ``Y`` (frames done, n) and ``charts`` the states after each frame; with ``sampling``,
        ``samples`` are their ``sample`` (taken in the same call; None when an evaluation failed
        there, or without ``sampling``). The run's contacts' memory must be empty (fixed steps are
        batched only without contacts)."""
        if _c(y) is not y or _c(chart) is not chart:
            raise ValueError("the kernel steps y and chart in place: they must be C-contiguous float64 arrays")
        self._fresh(elements)
        Y, charts = np.empty((n_frames, y.shape[0])), np.empty((n_frames, *chart.shape))
        out = self._samples(n_frames if sampling else 0)
        sampled = np.array([int(sampling)], np.int64)
        done, partial, status = self._frames_call(n_frames, every, n0, t0, h, y, chart, switches, max_speed, Y, charts,
                                                  np.empty(n_frames), sampled, out, self.ws[0])
        samples = Samples(*(a[:done] for a in out)) if sampled[0] == 1 else None
        return Y[:done], charts[:done], done, partial, status, samples

    def _frames_call(self, n_frames, every, n0, t0, h, y, chart, switches, max_speed, Y, charts, ts, sampled, out, v):
        """``advance_frames`` with this stepper's tableau (an empty one for a stepper without: sampling
        only), model, view ``v`` and workspace."""
        d, tab = self.data, self.tableau
        ta, tb, tc = (_c(tab.a), _c(tab.b), _c(tab.c)) if tab is not None else (np.zeros((0, 0)), np.zeros(0),
                                                                               np.zeros(0))
        group = int(tab is not None and not tab.embedded)
        return self._call(advance_frames, n_frames, every, n0, t0, h, y, chart, switches, ta, tb, tc, group, max_speed,
                          d.model, v, self.ws[1], d.forces, d.rows, d.memories, self._k, self._yi, Y, charts, ts, sampled,
                          d.geometry, d.energies, np.empty(self._yi.shape[0]), *out)

    def adaptive(self, carry: AdaptiveCarry, n_frames: int, every: int, n0: int, t_start: float, dt: float,
                 t_end: float, controller, events: tuple, memory: tuple, contact_mode: bool, max_speed: float,
                 max_turn: float, records: StepRecords | None = None, replant: bool = False
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int, int]:
        """Up to ``n_frames`` output frames of an adaptive run, ``every`` samples ``dt`` apart, the
        first after sample ``n0`` of a run started at ``t_start`` [s], no step past ``t_end`` [s],
        advancing ``carry`` in place (``viz3d.kernel.adaptive.adaptive_frames``) under ``controller``
        (``adaptive.Controller``),
        with the contacts' ``events`` (``viz3d.events.EventRow``) and memory ``memory``, each accepted
        step into ``records`` when given (from ``records.n[0]`` on); with ``replant`` the stick anchors
        of the contacts' bristles move after each step (in a copy of ``memory``'s rows, recorded). Returns
        ``(Ts, Y, charts, frames done, samples done in the next frame, status)``, the first three
        over the frames done: times (N,) [s], states (N, n), charts (N, nf, 3, 3)."""
        from viz3d.kernel.adaptive import EVENT_KINDS, adaptive_frames

        d, tab = self.data, self.tableau
        if self._method is None or self._method[0] != controller:
            self._method = controller, _adaptive_method(tab, controller)
        n, nf = carry.y.shape[0], carry.chart.shape[0]
        kind = np.array([EVENT_KINDS[e.kind] for e in events], np.int64)
        index = np.array([e.index for e in events], np.int64)
        floor = np.array([e.floor for e in events], float)
        direction = np.array([e.direction for e in events], np.int64)
        z = np.empty
        scratch = (z(n), z(n), z(n), z(n), z((nf, 3, 3)), np.zeros(carry.switches.shape[0], np.int64),
                   z((d.n_contacts, 11)), z((len(events), 2)), z((len(events), 2)), z(n), z((d.n_contacts, MEMORY_COLUMNS)))
        Ts, Y, charts = z(n_frames), z((n_frames, n)), z((n_frames, nf, 3, 3))
        record = records is not None
        records = records if record else StepRecords.empty(0, n, nf, d.n_contacts)
        view = self.ws[0]._replace(mem=memory_table(d, memory)) if replant else self.view(memory)  # (moved: not kept)
        done, partial, status = self._call(
            adaptive_frames, n_frames, every, n0, t_start, dt, t_end, int(contact_mode), max_speed, max_turn,
            *self._method[1], kind, index, floor, direction, int(record), *records, d.model, view, self.ws[1], d.forces,
            d.rows, d.geometry, d.replants, int(replant), *carry, self._k, *scratch, Y, charts, Ts)
        return Ts[:done], Y[:done], charts[:done], done, partial, status


def _adaptive_method(tableau, controller) -> tuple:
    """The tableau and ``controller`` (``adaptive.Controller``, or ``FixedSteps``: no error test,
    no continuous extension) as the compiled driver takes them."""
    from viz3d.integrators.adaptive import (EVENT_MAXITER, EVENT_RTOL, EVENT_XTOL, FAC_MAX, FAC_MIN, ROUNDING, SAFETY,
                                            FixedSteps)
    from viz3d.integrators.explicit_rk import is_end_stage

    c, s = np.ascontiguousarray, len(tableau.b)
    if isinstance(controller, FixedSteps):
        steps = [np.nan, np.nan, controller.max_step, 0.0, np.nan, SAFETY, FAC_MIN, FAC_MAX]
        fixed = [controller.dt, float(not tableau.embedded)]  # (group steps: as ExplicitRK's and the kernel's rk_step)
        P, c_extra, a_extra = np.zeros((s, 0)), np.zeros(0), np.zeros((0, s))
    else:
        steps = [controller.rtol, controller.atol, controller.max_step, controller.min_step, tableau.estimate_order,
                 SAFETY, FAC_MIN, FAC_MAX]
        fixed = [0.0, 0.0]
        dense = tableau.dense
        P, c_extra = dense.P, dense.c_extra
        a_extra = dense.a_extra if dense.a_extra.size else np.zeros((0, s))
    ctrl = np.array(steps + [EVENT_XTOL, EVENT_RTOL, EVENT_MAXITER, ROUNDING] + fixed, float)
    reuse = np.array([is_end_stage(tableau, row) for row in a_extra], np.int64)
    return (ctrl, c(tableau.a), c(tableau.b), c(tableau.error_weights), c(tableau.c), bool(tableau.fsal), c(P),
            c(c_extra), c(a_extra), reuse)


def kernel_advance(data: KernelData, tableau, n_steps: int, t0: float, h: float, y: np.ndarray, chart: np.ndarray,
                   switches: np.ndarray, max_speed: float) -> tuple[int, int]:
    """Advance ``y`` and ``chart`` in place by up to ``n_steps`` steps; (steps done, status)."""
    return KernelStepper(data, tableau).step(t0, h, y, chart, switches, max_speed, n_steps)
