"""Compiled pieces: numba's ``njit`` with viz3d's options, and the registry that composes the kernel.

The compiled kernel (``viz3d.kernel``) keeps what is generic: the bodies' kinematics and mass
blocks, the assembly and banded solve of the constraint rows, the Runge-Kutta loop. What an element
does (a spring's force, a ball joint's rows, a normal law's magnitude) is its **compiled piece**,
written next to its NumPy code and registered here for one of its **targets** (``TARGETS``):

* ``force_piece(d, t, v, power)``: force elements and law contacts add their generalized forces to
  ``v`` and the power that is not in a potential energy to ``power`` (the ledger's work rates);
* ``row_piece(d, t, v)``: a row provider (joint set, kinematic contacts) fills its constraint rows;
* ``gap_piece(d, v, out)``: contacts write their indentation, its rate (the event functions), normal,
  separation and contact point;
* ``normal_force(d, k, p0, alpha, alpha_dot, approach_speed, alpha_max, clip)``: a normal law's magnitude
  (its parameters in ``d.f[k, p0:]``), clipped at zero (``NormalLaw.force``) or not (``force_unclipped``);
* ``energy_piece(d, v, V)``: force elements with a potential energy add it to ``V`` (output frames;
  a force element whose ``potential_energy`` is its own must have one, or frames take the NumPy path);
* ``after_step_piece(d, t, v)``: force elements with a memory (``ForceElement.has_memory``) renew it
  after each accepted step of the kernel's fixed-step loop, from the state in ``v`` at its end
  (``memory_after_step``); the memory lives in arrays of ``d``, fixed during a step;
* ``replant_piece(d, t, v)``: law contacts move the stick anchors of their bristle friction (the
  contacts' memory rows ``v.mem``) after each accepted step of the compiled adaptive driver
  (``viz3d.events.ContactStepping._replant``): only that driver takes them (``KernelData.replants``),
  so the other entries do not compile them;
* ``hold_piece(d, t, v, mode, tol)``: force elements with branches (``ForceElement.branches``) hold
  them as they are at the kinematics in ``v`` (``HOLD``: ``ForceElement.frozen``), evaluate with their
  own again (``RELEASE``), or count those found in ``v`` that differ from the held ones beyond
  positions within ``tol`` [m] (``CHANGE``: ``ForceElement.frozen_change``); what is held lives in
  arrays of ``d`` (the compiled ALI3-P's steps, ``viz3d.kernel.ali3p``).

``d`` is the element's packed data: an instance of its own ``Items`` subclass (a named tuple of an
int64 table ``i`` and a float64 table ``f``, one row per item; the columns are the piece's
business), or of a subclass of it. The target dispatches on that class at compile time
(``numba.extending.overload``; a class and its subclass may not both register for one target), so
the kernel loops over a tuple of data, one entry per registered class, without knowing the
elements: one compiled signature whatever the system holds. A class with ``Items.present_only``
(data of many arrays: the shape contacts') is in those tuples only when the system has items of
it, and gives the kernel a second signature: numba passes every array of a tuple, flattened, at
each call of a compiled function that takes it, so an empty entry of some 75 arrays made every
RK stage of every system push some 1,600 more words (the torque-free body's RK4 step 1.1 -> 8.4
us). ``v`` is the kernel's ``View`` (``viz3d.kernel.model``): the material points' kinematics, the
frames' rotations, the generalized forces and the constraint rows; pieces never see bodies, they
read points and write through the helpers of ``viz3d.points``.

Compiled functions are cached on disk (numba ``cache=True``). numba checks a cache entry against
the source file of the function itself only, so an edit of a piece would leave the kernel that
inlines it stale; here every compiled function of viz3d (and of registered pieces elsewhere) is
keyed by one stamp of all those source files instead. Compiled with ``error_model="numpy"``: a
division by zero gives inf or nan, which the step's health checks report (numba's default would
raise out of the run and lose its frames).

A cache hit skips numba's target refresh (``LoadingCache``): before every load numba imports and
installs the typing and lowering of all it supports (NRT, typed containers, linear algebra and
scipy.linalg, ...), 0.1-0.2 s at a run's start, in case the loaded code needs them. viz3d's does
not (no NRT, no object mode); a miss compiles, and numba's compiler refreshes first. Nor does a
cache hit parse the bitcode numba keeps with a compiled entry for linking it into later compilations
(0.1 s for the kernel's ``advance_frames``): that is parsed when a compilation links it. And the
cache directory is located when a function is first loaded or compiled, not as it is decorated.
The first compilation in a process makes numba's inliner copy less (``_cheaper_inlining``: the same
code, compiled with about a tenth less CPU) and its linker optimize each compiled callee once
(``_link_optimized_callees``: a tenth to a quarter less); a callee compiles once per argument
type, not once per constant its callers pass (``_one_signature_per_type``).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import inspect
import sys
import weakref
from pathlib import Path
from typing import NamedTuple

import numpy as np

try:  # numba is optional: without it every run takes the NumPy path
    import numba
    from numba import types
    from numba.extending import overload
except ImportError:  # pragma: no cover - exercised only where numba is missing
    numba = None

#: Options of every compiled function of viz3d. ``_nrt=False``: no reference counting of arrays. The
#: compiled code never allocates (every scratch array comes from ``viz3d.kernel.model.workspace``),
#: and counting references cost more than the arithmetic: each call and each row view (``v3[2]``,
#: ``R[b]``) took and released one atomic reference per array (the right-hand side of a 2-link
#: chain took twice as long). An allocation in compiled code is then a compile error.
JIT_OPTIONS = {"cache": True, "error_model": "numpy", "_nrt": False}
#: ... and of those called only from compiled code: no wrappers for calls from Python (the wrapper
#: that unboxes the kernel's named tuples of arrays costs more to compile than most functions).
INNER_OPTIONS = dict(JIT_OPTIONS, no_cpython_wrapper=True, no_cfunc_wrapper=True)

PACKAGE = Path(__file__).resolve().parent


def jit(fn):
    """``fn`` compiled by numba, to be called from compiled code only (``INNER_OPTIONS``; ``fn``
    itself without numba)."""
    if numba is None:
        return fn
    return _njit(fn, INNER_OPTIONS)


def inline(fn):
    """``fn`` inlined into its callers by numba (for a stage called once: a separate compiled
    function taking the kernel's named tuples costs more to compile than its body)."""
    if numba is None:
        return fn
    return _njit(fn, dict(INNER_OPTIONS, inline="always"))


def entry(fn):
    """``fn`` compiled by numba, callable from Python too (``JIT_OPTIONS``)."""
    if numba is None:
        return fn
    return _njit(fn, JIT_OPTIONS)


def _njit(fn, options: dict):
    """``numba.njit(**options)(fn)``, cached on disk by a ``LoadingCache`` (``options["cache"]``);
    every signature compiles under a lock (``_lock_compiles``)."""
    dispatcher = numba.njit(**dict(options, cache=False))(fn)
    if options.get("cache") and hasattr(dispatcher, "enable_caching"):  # not with NUMBA_DISABLE_JIT
        if LoadingCache is None:  # pragma: no cover - another numba
            dispatcher.enable_caching()
        else:
            dispatcher._cache = LoadingCache(dispatcher.py_func)  # what enable_caching does, our class
        _lock_compiles(dispatcher)
    if hasattr(dispatcher, "compile"):
        _one_signature_per_type(dispatcher)
    if hasattr(dispatcher, "_compilation_chain_init_hook"):
        dispatcher._compilation_chain_init_hook = _extensions_when_compiling
    return dispatcher


def _extensions_when_compiling() -> None:
    """What a call of a viz3d function from Python does where numba's dispatcher initializes numba's
    extensions (``numba.core.entrypoints.init_all``, every ``numba_extensions`` entry point of the
    installed packages, for types and functions defined outside numba): nothing. Their scan of every
    installed distribution's metadata took 10-40 ms of a run's start (76 distributions here) and a
    run that loads its kernel from the cache compiles nothing; the arguments viz3d passes are arrays,
    numbers and its own named tuples, typed without them. The extensions are initialized as numba
    starts the first compilation in the process (``_before_the_first_compilation``), as numba's own
    functions initialize them on their first call."""


def _init_extensions() -> None:
    """numba's extensions initialized (``_extensions_when_compiling``)."""
    from numba.core import entrypoints

    entrypoints.init_all()


def _one_signature_per_type(dispatcher) -> None:
    """Make ``dispatcher`` compile for the types of its arguments, not for the constants a caller
    passes: numba types a constant argument in compiled code as a literal (``Literal[int](0)``,
    ``Literal[bool](True)``) and compiles a callee once per constant, though the machine code
    differs only in what LLVM folds. ``_branches`` of ``viz3d.kernel.ali3p``, called with its three
    modes, was compiled three times and ``_iterate`` twice (measured on the anchor hoist's ALI3-P
    signature: 18 s of 121 s of CPU). A function that cannot be typed without the constant (a
    tuple indexed by it) still compiles for it."""
    from numba.core import errors, sigutils, types

    compile_ = dispatcher.compile

    def compile(sig):
        args, return_type = sigutils.normalize_signature(sig)
        plain = tuple(types.unliteral(a) for a in args)
        if plain != tuple(args):
            try:
                return _owned(dispatcher, compile_(plain if return_type is None else return_type(*plain)))
            except errors.TypingError:
                pass
        return _owned(dispatcher, compile_(sig))

    dispatcher.compile = compile


#: The code libraries of viz3d's compiled functions (``_link_optimized_callees``).
_OWN_LIBRARIES: "weakref.WeakSet" = weakref.WeakSet()


def _owned(dispatcher, entry_point):
    """``entry_point``, its dispatcher's compiled libraries noted as viz3d's."""
    for cres in dispatcher.overloads.values():
        library = getattr(cres, "library", None)
        if library is not None:
            _OWN_LIBRARIES.add(library)
    return entry_point


def _lock_compiles(dispatcher) -> None:
    """Make ``dispatcher`` compile each signature under a lock file in its cache directory.

    Processes that start together on a cold cache (a study's or the test suite's workers) would each
    compile the kernel, minutes of CPU apiece; with the lock one compiles a signature and saves it,
    and the others, waiting, then load it from the cache (numba's ``compile`` looks there first).
    The lock is taken inside numba's compiler lock (re-entrant), so the order of the two is the same
    in every thread. Functions compiled inside another's compilation (its callees) take their own
    lock too, so two workers compiling different entries share the callees both need (the rigid
    kernel's ``project`` and ``fill_rows``, 27 s of CPU, were compiled by both of the suite's
    workers): a process holds the locks of a chain of callers and callees, taken callers first, and
    as no compiled function calls back into its callers no two processes can wait on each other (a
    process re-entering a lock it holds, a function compiled within its own compilation, passes).
    Where no lock file can be made (no ``fcntl``, a cache directory that cannot be written)
    compiling goes on unlocked, as numba's own does."""
    compile_ = dispatcher.compile

    def compile(sig):
        from numba.core import sigutils
        from numba.core.compiler_lock import global_compiler_lock

        args, _ = sigutils.normalize_signature(sig)
        if tuple(args) in dispatcher.overloads:
            return compile_(sig)
        with global_compiler_lock, _file_lock(_lock_path(dispatcher, args)):
            return compile_(sig)

    dispatcher.compile = compile


def _lock_path(dispatcher, args) -> Path | None:
    """The lock file of ``dispatcher``'s signature ``args`` in its cache directory, or None."""
    try:
        directory = Path(dispatcher._cache._cache_path)
        directory.mkdir(parents=True, exist_ok=True)
    except (AttributeError, OSError):  # pragma: no cover - another numba, a read-only cache
        return None
    key = hashlib.sha1(repr(tuple(args)).encode()).hexdigest()[:16]
    return directory / f"{dispatcher.py_func.__qualname__}-{key}.lock"


#: The lock files this process holds (``_file_lock``).
_HELD: set[Path] = set()


@contextlib.contextmanager
def _file_lock(path: Path | None):
    """An exclusive ``flock`` on ``path`` while the block runs (nothing when ``path`` is None, the
    platform has no ``fcntl``, or this process holds it already)."""
    try:
        import fcntl
        handle = None if path is None or path in _HELD else open(path, "a")
    except (ImportError, OSError):  # pragma: no cover - Windows, a read-only cache
        handle = None
    if handle is None:
        yield
        return
    with handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        _HELD.add(path)
        try:
            yield
        finally:
            _HELD.discard(path)
            fcntl.flock(handle, fcntl.LOCK_UN)


class Items(NamedTuple):
    """Packed data of one element type: ``i`` (k, ni) int64 and ``f`` (k, nf) float64, one row per
    item. Each element type subclasses it (the subclass is what selects its compiled piece)."""

    i: np.ndarray
    f: np.ndarray
    #: True: in the kernel's tuples of data only when the system has items of this class (see the
    #: module docstring); for classes of many arrays.
    present_only = False


def items(cls: type[Items], i=None, f=None, k: int = 0) -> Items:
    """An instance of ``cls`` from tables (rows = items); missing tables are empty (k, 0)."""
    i = np.zeros((k, 0), np.int64) if i is None else np.ascontiguousarray(np.asarray(i, dtype=np.int64).reshape(k, -1))
    f = np.zeros((k, 0)) if f is None else np.ascontiguousarray(np.asarray(f, dtype=float).reshape(k, -1))
    return cls(i, f)


def concat(cls: type[Items], parts: list[Items]) -> Items:
    """Items of several element sets of one type as one (rows stacked)."""
    if not parts:
        return items(cls)
    if len(parts) == 1:
        return parts[0]
    return cls(np.ascontiguousarray(np.concatenate([p.i for p in parts])),
               np.ascontiguousarray(np.concatenate([p.f for p in parts])))


# ---------------------------------------------------------------------------- targets


def force_piece(d, t, v, power):
    """Add the generalized forces of the elements ``d`` at time ``t`` to ``v`` and their
    non-potential power to ``power``."""
    raise NotImplementedError  # dispatched at compile time


def row_piece(d, t, v):
    """Fill the constraint rows of the row provider ``d`` in ``v``."""
    raise NotImplementedError


def gap_piece(d, v, out):
    """Write the gap of the contacts ``d`` into their rows of ``out`` (n_contacts, 11): ``alpha``,
    ``alpha_dot``, then the world normal, ``a - b`` and the contact point, 3 each (the fields of
    ``viz3d.contact.contacts.Gap``)."""
    raise NotImplementedError


def normal_force(d, k, p0, alpha, alpha_dot, approach_speed, alpha_max, clip):
    """Normal force magnitude of contact ``k`` of ``d`` (``viz3d.contact.laws``) [N], >= 0 when ``clip``
    (else the formula, which may pull: ``NormalLaw.force_unclipped``), the law's parameters in ``d.f[k, p0:]``."""
    raise NotImplementedError


def energy_piece(d, v, V):
    """Add the potential energy [J] of the elements ``d`` (positions in ``v``) to ``V`` (2,):
    ``V[0]`` the part that may be negative (gravity, loads), ``V[1]`` the part that may not (springs)
    (``viz3d.events.Ledger``'s ``signed_potential`` and the rest of ``potential``)."""
    raise NotImplementedError


def after_step_piece(d, t, v):
    """Renew the memory of the elements ``d`` after an accepted step ending at time ``t`` (the state's
    kinematics in ``v``)."""
    raise NotImplementedError


def replant_piece(d, t, v):
    """Move the stick anchors of the contacts ``d`` in their memory rows ``v.mem`` after an accepted
    step ending at time ``t`` (the state's kinematics in ``v``)."""
    raise NotImplementedError


#: ``hold_piece``'s modes (module docstring).
HOLD, RELEASE, CHANGE = 0, 1, 2


def hold_piece(d, t, v, mode, tol):
    """Hold, release or compare the branches of the elements ``d`` at the kinematics in ``v``
    (``mode``: ``HOLD``, ``RELEASE``, ``CHANGE``); the number of branches that differ (``CHANGE``), else 0."""
    raise NotImplementedError


#: Targets in order: a data class registered for several belongs to the first (its packing group).
TARGETS = (force_piece, row_piece, gap_piece, normal_force, energy_piece, after_step_piece, replant_piece, hold_piece)

#: Registered data classes per target, in registration order.
REGISTRY: dict[str, list[type[Items]]] = {t.__name__: [] for t in TARGETS}
#: Source files of the registered pieces (part of the cache stamp).
_SOURCES: set[str] = set()


def compiled_piece(target, data_class: type[Items]):
    """Decorator: register ``fn`` as the compiled piece of ``target`` for data of ``data_class``.

    ``fn`` takes the target's arguments. Returns ``fn`` compiled (or unchanged without numba).
    """
    if not (isinstance(data_class, type) and issubclass(data_class, Items)):
        raise TypeError(f"{data_class!r} must subclass viz3d.compiled.Items")

    def register(fn):
        for other in REGISTRY[target.__name__]:
            if issubclass(other, data_class) or issubclass(data_class, other):
                raise TypeError(f"{data_class.__name__} and {other.__name__} would both select {target.__name__}")
        REGISTRY[target.__name__].append(data_class)
        _SOURCES.add(inspect.getfile(fn))
        if numba is None:
            return fn
        compiled = jit(fn)

        def choose(d):
            if isinstance(d, types.BaseNamedTuple) and issubclass(d.instance_class, data_class):
                return fn  # compiled as the implementation itself (no wrapper layer)
            return None

        overload(target, jit_options=INNER_OPTIONS)(_typer(target, choose))
        return compiled

    return register


def _typer(target, choose):
    """An overload typing function with exactly the parameters of ``target`` (numba requires the
    typer's signature to be the implementation's) that returns ``choose(first argument)``."""
    params = list(inspect.signature(target).parameters)
    namespace = {"choose": choose}
    exec(f"def select({', '.join(params)}):\n    return choose({params[0]})\n", namespace)
    return namespace["select"]


def target_of(data_class: type[Items]):
    """The target ``data_class`` (or a base of it) is registered for, or None."""
    for target in TARGETS:
        if any(issubclass(data_class, c) for c in REGISTRY[target.__name__]):
            return target
    return None


def registered(target) -> tuple[type[Items], ...]:
    """The data classes with a compiled piece for ``target``, in a canonical order (module and name:
    the kernel's argument types, hence its compiled code, do not depend on import order)."""
    return tuple(sorted(REGISTRY[target.__name__], key=lambda c: (c.__module__, c.__qualname__)))


# ---------------------------------------------------------------------------- cache stamp


def _stamp(files: tuple[str, ...]) -> str:
    h = hashlib.sha256()
    for name in files:
        try:
            h.update(Path(name).read_bytes())
        except OSError:
            h.update(name.encode())
    return h.hexdigest()


def stamped_files() -> tuple[str, ...]:
    """The source files with compiled code: this module, every module of viz3d that imports it,
    and the files of pieces registered from elsewhere (independent of import order)."""
    return tuple(sorted(set(_package_sources()) | _SOURCES))


def source_stamp() -> str:
    """One hash of ``stamped_files``: the key of every cached compiled function of viz3d.

    Hashed once per set of files in a process (numba asks for it once per compiled function, 80 and
    more at start): a process compiles the code it imported, so a file edited while it runs must
    not change its key (it would store the old code under the new file's stamp)."""
    return _stamp_cached(stamped_files())


@functools.lru_cache(maxsize=8)
def _stamp_cached(files: tuple[str, ...]) -> str:
    return _stamp(files)


@functools.cache
def _package_sources() -> tuple[str, ...]:
    """``compiled.py`` and the modules of viz3d that import it (the package is read once per process)."""
    return tuple(str(p) for p in PACKAGE.rglob("*.py") if p.name == "compiled.py" or _uses_compiled(p))


def _uses_compiled(path: Path) -> bool:
    try:
        return "viz3d.compiled import" in path.read_text(encoding="utf-8")
    except OSError:
        return False


def _install_stamp_locators() -> None:
    """Make numba key the cache of viz3d's compiled functions on ``source_stamp``.

    Wraps numba's own file-system locators (the user's ``NUMBA_CACHE_DIR``, ``__pycache__`` next to
    the source, the user-wide cache); other files keep numba's behaviour. Without these private
    classes (another numba) nothing changes: caches are then keyed per file, as numba does.
    """
    try:
        from numba.core import caching
    except ImportError:  # pragma: no cover
        return
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)  # renamed in numba 0.6x
    bases = [getattr(caching, name, None) or getattr(caching, "_" + name, None)
             for name in ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator")]
    if impl is None or not hasattr(impl, "_locator_classes") or None in bases:  # pragma: no cover
        import warnings

        warnings.warn(f"numba {numba.__version__}: cannot key the kernel cache on all of viz3d's compiled "
                      "sources; after an edit of an element's piece, clear the numba cache", RuntimeWarning,
                      stacklevel=2)
        return
    ours = []
    for base in bases:
        def from_function(cls, py_func, py_file):
            if not _is_ours(py_file):
                return None
            return super(cls, cls).from_function(py_func, py_file)

        ours.append(type("Viz3d" + base.__name__.lstrip("_"), (base,), {
            "get_source_stamp": lambda self: source_stamp(),
            "from_function": classmethod(from_function),
        }))
    if not any(c.__name__.startswith("Viz3d") for c in impl._locator_classes):
        impl._locator_classes[:0] = ours


def _is_ours(py_file: str) -> bool:
    path = Path(py_file).resolve()
    return PACKAGE in path.parents or str(path) in _SOURCES


def _loading_cache():
    """numba's cache of a function, made cheap at a run's start, or None when this numba lacks the
    private pieces it builds on (the cache is numba's own then). Three things numba does at once are
    done only when needed:

    * the target refresh before a load, for code that needs the target at run time: the NRT (viz3d
      compiles with ``_nrt=False``), object-mode blocks (none here), typed containers. Compiling,
      the one thing that needs the typing and lowering, refreshes first in numba's compiler;
    * locating and probing the cache directory, for each of the 204 compiled functions as it is
      decorated: on the first load or save of that function (``__getattr__``);
    * parsing the bitcode a loaded entry keeps for linking into other libraries (megabytes for the
      kernel's entries, 0.1 s of a run's start), which a call from Python never needs: when a later
      compilation links the entry (``LinkLaterLibrary``). The names the entry defines, which numba
      reads from that bitcode, are stored with it (``LinkLaterImpl.reduce``);
    * importing the module of every compiled function's environment as the entry is unpickled
      (``numba.core.environment._rebuild_env``): the kernel inlines a few of numba's own
      implementations (``normalize_reshape_value`` of ``numba.np.arrayobj``, 33 ms to import, and
      three smaller), and their environments' globals are read only by object-mode code, which
      viz3d's compiled code has none of (``_lazy_env``);
    * importing the modules of the argument types of every signature in a function's cache index as
      the index is read to find the one entry wanted: the kernel's ``advance_frames`` is cached for
      systems with shape contacts too (their data class in ``viz3d.kernel.collisions``, which
      imports the narrow phase: 10-15 ms), and a rigid run's signature needs none of them. A class
      whose module is not imported yet reads as a stand-in (``_IndexUnpickler``), so those
      signatures differ from the one looked up, which holds the caller's own classes; numba's save
      of a new entry (a compilation) reads the index again with every class, the stand-ins never
      written.
    """
    try:
        import io
        import pickle

        from llvmlite import binding as ll
        from numba.core import caching, environment
        from numba.core.caching import CompileResultCacheImpl, FunctionCache, IndexDataCacheFile
        from numba.core.codegen import JITCodeLibrary, JITCPUCodegen, JitEngine
    except ImportError:  # pragma: no cover
        return None
    needs = {FunctionCache: ("_load_overload", "_guard_against_spurious_io_errors"),
             JITCodeLibrary: ("_get_module_for_linking", "_set_compiled_object", "enable_object_caching",
                              "_finalize_final_module"),
             JitEngine: ("is_symbol_defined", "_load_defined_symbols"),  # the latter fills ``_defined_symbols``
             environment: ("_rebuild_env", "lookup_environment", "Environment"),
             IndexDataCacheFile: ("_load_index",), caching: ("pickle",)}
    if JITCPUCodegen._library_class is not JITCodeLibrary or not all(
            hasattr(cls, m) for cls, names in needs.items() for m in names):
        return None  # pragma: no cover
    rebuild_env = environment._rebuild_env

    def _lazy_env(modname, consts, env_name):
        """numba's ``_rebuild_env`` without importing ``modname``: an environment of a module not
        imported yet gets globals holding only its ``__name__`` (what numba's ``can_cache`` and
        pickling read); nopython code reads only the constants."""
        if modname in sys.modules or environment.lookup_environment(env_name) is not None:
            return rebuild_env(modname, consts, env_name)
        env = environment.Environment({"__name__": modname})
        env.consts[:] = consts
        env.env_name = env_name
        environment.Environment._memo[env_name] = env
        return env

    class _NotImported:
        """Base of the stand-ins for classes whose modules are not imported (``_IndexUnpickler``)."""

    stand_ins: dict[tuple[str, str], type] = {}

    class _IndexUnpickler(pickle.Unpickler):
        def find_class(self, module, name):
            if module not in sys.modules:
                if (module, name) not in stand_ins:
                    stand_ins[module, name] = type(name, (_NotImported,), {"__module__": module, "__qualname__": name})
                return stand_ins[module, name]
            return super().find_class(module, name)

    class _IndexPickle:
        """``pickle`` as numba's ``_load_index`` uses it, reading the index with ``_IndexUnpickler``."""

        load = staticmethod(pickle.load)

        @staticmethod
        def loads(data):
            return _IndexUnpickler(io.BytesIO(data)).load()

    def _index_of(cache_file):
        """``cache_file._load_index`` without importing modules (under numba's compiler lock);
        read with every class where a stand-in cannot take a class's place (it is called, say)."""
        caching.pickle = _IndexPickle
        try:
            return IndexDataCacheFile._load_index(cache_file)
        except Exception:
            caching.pickle = pickle
            return IndexDataCacheFile._load_index(cache_file)
        finally:
            caching.pickle = pickle

    class LinkLaterLibrary(JITCodeLibrary):
        """A library loaded from the cache (object code), its module for linking parsed on demand."""

        _shared_bitcode = None

        @classmethod
        def _unserialize(cls, codegen, state):  # numba's, for ("object", data) with the defined names
            name, kind, (object_code, shared_bitcode, defined) = state
            self = cls(codegen, name)
            self.enable_object_caching()
            self._set_compiled_object(object_code)
            self._shared_bitcode = shared_bitcode
            self._finalize_final_module()
            codegen._engine._defined_symbols.update(defined)
            return self

        def _get_module_for_linking(self):
            if self._shared_module is None and self._shared_bitcode is not None:
                self._shared_module = ll.parse_bitcode(self._shared_bitcode)
            return super()._get_module_for_linking()

    class LinkLaterImpl(CompileResultCacheImpl):
        """numba's cache entries, the library's payload ``(object code, bitcode for linking, defined
        names)``, loaded as a ``LinkLaterLibrary``."""

        def reduce(self, cres):
            (name, kind, data), *rest = super().reduce(cres)
            shared = cres.library._get_module_for_linking()
            defined = tuple(sorted(g.name for gs in (shared.functions, shared.global_variables) for g in gs
                                   if not g.is_declaration))
            return ((name, kind, (*data, defined)), *rest)

        def rebuild(self, target_context, payload):
            codegen = target_context.codegen()
            codegen._library_class = LinkLaterLibrary  # numba's compiler lock is held: no other load sees it
            try:
                return super().rebuild(target_context, payload)
            finally:
                del codegen._library_class

    class LoadingCache(FunctionCache):
        _impl_class = LinkLaterImpl

        def __init__(self, py_func):
            source_stamp()  # the key is the code this process imported, whenever the cache is set up
            self._pending = py_func

        def __getattr__(self, name):
            """Set numba's cache up on the first use of an attribute that its set-up defines."""
            py_func = vars(self).get("_pending")
            if py_func is None:
                raise AttributeError(name)
            self._pending = None
            try:
                super().__init__(py_func)
            except BaseException:
                self._pending = py_func
                raise
            return getattr(self, name)

        def load_overload(self, sig, target_context):
            # Under numba's compiler lock (``Dispatcher.compile``): the entry is unpickled here,
            # pickle reading ``environment._rebuild_env`` as it meets each environment.
            # The index is read with stand-ins for classes not imported (``_index_of``) by this load only.
            environment._rebuild_env = _lazy_env
            self._cache_file._load_index = functools.partial(_index_of, self._cache_file)
            try:
                with self._guard_against_spurious_io_errors():
                    return self._load_overload(sig, target_context)
            finally:
                environment._rebuild_env = rebuild_env
                del self._cache_file._load_index

    return LoadingCache


#: Edits of numba's inliner (``InlineWorker.inline_ir``), ``(numba's text, ours)``: ``copy_ir`` copies
#: the blocks in one deep copy, not one per block; the two copies of the callee are skipped for a
#: callee IR built for this call (``fresh``).
_INLINER_EDITS = (
    ("""        for block_label, block in the_ir.blocks.items():
            new_block = copy.deepcopy(the_ir.blocks[block_label])
            kernel_copy.blocks[block_label] = new_block
""", """        kernel_copy.blocks = copy.deepcopy(the_ir.blocks)
"""),
    ("arg_typs=None):", "arg_typs=None, fresh=False):"),
    ("callee_ir = copy_ir(callee_ir)", "callee_ir = callee_ir if fresh else copy_ir(callee_ir)"),
    ("callee_ir_original = copy_ir(callee_ir)", "callee_ir_original = callee_ir if fresh else copy_ir(callee_ir)"),
)
#: What numba's ``InlineWorker.inline_function`` does (the calls ``_cheaper_inlining`` replaces it with).
_INLINE_FUNCTION = ("callee_ir = self.run_untyped_passes(function)", "return self.inline_ir(caller_ir, block, i, callee_ir, freevars,")


def _cheaper_inlining() -> bool:
    """Make numba's inliner copy less (True); False (numba left as it is) where its source is not the
    one this was written for. The kernel's stages are inlined into each other (``inline``), and
    copying their IR was about a quarter of compiling the kernel (numba issues 8989 and 9204):

    * ``inline_function`` (what ``inline`` uses) builds the callee's IR for the call, which nobody
      else holds, and ``inline_ir`` then deep-copied it twice: once to work on, once to return
      unchanged (which numba's callers drop). Such a fresh IR is now inlined as it is;
    * where ``inline_ir`` still copies (an IR it is given), it copied each block on its own. Every
      block refers to the function's one scope, which holds all its variables, so each block's copy
      copied the whole scope again: blocks x variables. One copy of all the blocks copies it once,
      shared by the copied blocks as by the original ones.

    The compiled code is the same (runs of the rigid, adaptive, contact and ALI3-P kernels are
    bit-identical), its compilation cheaper; measured on a cold cache, the code before and after side
    by side, one on each core (2026-11-28): the scenes of the suite's first worker's warm-up
    (``tests/conftest.py``) 156.3 -> 144.6 s of CPU with the one copy of the blocks (made first), then
    160.2 -> 152.6 s with the fresh IR inlined as it is; the second worker's scenes (the hoist on RK4
    for 0.3 s, a chain on ALI3-P for 1 s) 239.9 -> 217.6 s with both."""
    import inspect
    import textwrap

    from numba.core import inline_closurecall

    worker = inline_closurecall.InlineWorker
    try:
        source = textwrap.dedent(inspect.getsource(worker.inline_ir))
        calls = inspect.getsource(worker.inline_function)
    except (OSError, TypeError):  # pragma: no cover - no source to read
        return False
    if any(source.count(old) != 1 for old, _ in _INLINER_EDITS) or not all(c in calls for c in _INLINE_FUNCTION):
        return False  # pragma: no cover - another numba
    for old, new in _INLINER_EDITS:
        source = source.replace(old, new)
    namespace: dict = {}
    exec(compile(source, inline_closurecall.__file__, "exec"), inline_closurecall.__dict__, namespace)
    worker.inline_ir = namespace["inline_ir"]

    def inline_function(self, caller_ir, block, i, function, arg_typs=None):
        """``function`` inlined at statement ``i`` of ``block``, its IR built for this call."""
        return self.inline_ir(caller_ir, block, i, self.run_untyped_passes(function), function.__code__.co_freevars,
                              arg_typs=arg_typs, fresh=True)

    worker.inline_function = inline_function
    return True


def _link_optimized_callees() -> bool:
    """Make numba link viz3d's compiled callees into a caller after optimizing the caller, not before
    (True; False where numba's code library is not the one this was written for).

    numba links every callee's optimized module into its caller's and optimizes the whole again:
    the callees of a deep call tree (``ali3p_frames`` -> ``_iterate`` -> ``_force_tangent`` ->
    ``_forces_and_rows`` -> the shape contacts' forces -> their narrow phase) were optimized once at
    every level above them. Each is now optimized once, in its own library, and the caller calls it
    (LLVM no longer inlines a viz3d callee into its caller; numba's own helpers, ``max`` and the
    like, are linked and inlined as before). The compiled code is the same (runs bit-identical) and
    as fast (torque_free, heavy_top, chain, flexible_pendulum and the hoist on RK4 and ALI3-P within
    the runs' 5 % spread); measured cold, the code before and after side by side (2026-11-28): the
    hoist on ALI3-P for 0.1 s 212.0 -> 195.6 s of CPU, then a chain on ALI3-P 59.3 -> 49.2 s, then
    flexible_pendulum 59.5 -> 43.7 s."""
    from numba.core import codegen

    library = getattr(codegen, "CPUCodeLibrary", None)
    try:
        source = inspect.getsource(library.finalize)
    except (AttributeError, OSError, TypeError):  # pragma: no cover - another numba
        return False
    steps = ("for library in self._linking_libraries:", "self._reload_init.update(library._reload_init)",
             "library._get_module_for_linking(), preserve=True", "self._optimize_final_module()")
    if not all(step in source for step in steps):  # (links them, then optimizes: what this reorders)
        return False  # pragma: no cover - another numba
    finalize_, optimize_ = library.finalize, library._optimize_final_module

    def finalize(self):
        linking = getattr(self, "_linking_libraries", None)
        if isinstance(linking, list):
            self._viz3d_after = [lib for lib in linking if lib in _OWN_LIBRARIES]
            self._linking_libraries = [lib for lib in linking if lib not in _OWN_LIBRARIES]
        return finalize_(self)

    def _optimize_final_module(self):
        optimize_(self)
        seen = set()
        for lib in getattr(self, "_viz3d_after", ()):
            if lib not in seen:
                seen.add(lib)
                self._reload_init.update(lib._reload_init)
                self._final_module.link_in(lib._get_module_for_linking(), preserve=True)
        self._viz3d_after = ()

    library.finalize, library._optimize_final_module = finalize, _optimize_final_module
    return True


def _before_the_first_compilation(change) -> None:
    """Run ``change()`` once, as numba starts its first compilation in this process (not at import:
    a run that loads its kernel from the cache never compiles)."""
    from numba.core import event

    class Once(event.Listener):  # (it stays registered: removing it while numba notifies its listeners
        done = False                # would skip the next one)

        def on_start(self, ev):
            if not self.done:
                self.done = True
                change()

        def on_end(self, ev):
            pass

    event.register("numba:compile", Once())


LoadingCache = None
if numba is not None:
    _install_stamp_locators()
    LoadingCache = _loading_cache()
    _before_the_first_compilation(_init_extensions)
    _before_the_first_compilation(_cheaper_inlining)
    _before_the_first_compilation(_link_optimized_callees)


# ---------------------------------------------------------------------------- small 3-vector helpers


@inline
def cross3(a, b, out):
    """``out = a x b`` (3,)."""
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@inline
def matvec3(A, x, out):
    """``out = A x`` for A (3, 3)."""
    for i in range(3):
        out[i] = A[i, 0] * x[0] + A[i, 1] * x[1] + A[i, 2] * x[2]


@inline
def tmatvec3(A, x, out):
    """``out = A^T x`` for A (3, 3)."""
    for i in range(3):
        out[i] = A[0, i] * x[0] + A[1, i] * x[1] + A[2, i] * x[2]


@inline
def dot3(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
