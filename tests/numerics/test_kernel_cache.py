"""The on-disk cache of the compiled kernel is keyed on every source file with compiled code: an
edit of one element's piece (say a contact's gap) must recompile the kernel functions that inline it,
whose own file did not change (numba alone keys a function on its own file). A load from the cache
does only what a call from Python needs."""

import os
import subprocess
import sys
import time

import pytest

numba = pytest.importorskip("numba")

from viz3d import compiled  # noqa: E402
from viz3d.contact import contacts  # noqa: E402
from viz3d.kernel import field, stepping  # noqa: E402


@pytest.mark.parametrize("fn", [field.rhs, field.gaps, stepping.advance_frames], ids=lambda f: f.py_func.__name__)
def test_kernel_entries_are_keyed_on_all_compiled_sources(fn):
    locator = fn._cache._impl.locator
    assert type(locator).__name__.startswith("Viz3d"), f"numba's own locator {type(locator).__name__} is in use"
    assert locator.get_source_stamp() == compiled.source_stamp()


def test_the_stamp_covers_the_pieces_and_changes_with_them(tmp_path, monkeypatch):
    files = compiled.stamped_files()
    for module in (contacts, field, compiled):
        assert module.__file__ in files
    before = compiled.source_stamp()
    copy = tmp_path / "contacts.py"
    copy.write_text(open(contacts.__file__, encoding="utf-8").read() + "\n# edited\n", encoding="utf-8")
    edited = tuple(str(copy) if f == contacts.__file__ else f for f in files)
    monkeypatch.setattr(compiled, "stamped_files", lambda: edited)
    assert compiled.source_stamp() != before


#: A module of compiled functions outside viz3d: an entry calling an inner function.
LINKED = """
from viz3d.compiled import entry, jit


@jit
def twice(x):
    return 2.0 * x


@entry
def total(a):
    s = 0.0
    for v in a:
        s += twice(v)
    return s
"""
#: Calls ``total`` (compiled, or loaded from the cache), then compiles a function that links it; prints
#: the cache hits, whether ``total``'s module for linking was parsed after the call, and after the link.
LINK_LATER = """
import sys
import time
sys.path.insert(0, {folder!r})
import numba
import numpy as np
import linked
a = np.arange(4.0)
assert linked.total(a) == 12.0
(cres,) = linked.total.overloads.values()
after_call = cres.library._shared_module is not None

@numba.njit
def plus_one(a):
    return linked.total(a) + 1.0

assert plus_one(a) == 13.0
print(sum(linked.total.stats.cache_hits.values()), after_call, cres.library._shared_module is not None)
"""


def test_a_loaded_entry_parses_its_module_for_linking_only_when_linked(tmp_path):
    """A cache hit loads an entry's object code; the bitcode numba keeps with it for linking into
    later compilations (megabytes for the kernel's entries, 0.1 s of a run's start to parse) is
    parsed only when a compilation links the entry, which then computes as one that links a freshly
    compiled entry (``viz3d.compiled.LoadingCache``)."""
    (tmp_path / "linked.py").write_text(LINKED, encoding="utf-8")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    code = LINK_LATER.format(folder=str(tmp_path))
    cold, warm = (subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
                  .stdout.split() for _ in range(2))
    assert cold == ["0", "True", "True"], "the first process compiles"
    assert warm == ["1", "False", "True"], "the second loads total and parses its bitcode when plus_one links it"


def test_decorating_sets_no_cache_up(tmp_path):
    """Importing the kernel (200 compiled functions) locates and probes no cache directory: numba
    does that for a function when it is first loaded or compiled (0.02 s of a run's start)."""
    cache = tmp_path / "cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    code = "import viz3d.kernel, viz3d.kernel.collisions\nassert viz3d.kernel.stepping.advance_frames._cache is not None"
    subprocess.run([sys.executable, "-c", code], env=env, check=True)
    assert not cache.exists()


#: Waits until the file ``go`` exists (after writing ``ready``), then calls ``total``; prints its cache
#: hits and misses.
RACE = """
import os, sys, time
sys.path.insert(0, {folder!r})
import numpy as np
import linked
open({ready!r}, "w").close()
while not os.path.exists({go!r}):
    time.sleep(0.001)
assert linked.total(np.arange(4.0)) == 12.0
print(sum(linked.total.stats.cache_hits.values()), sum(linked.total.stats.cache_misses.values()))
"""


def test_processes_starting_together_compile_an_entry_once(tmp_path):
    """Two processes that call a new entry at the same moment on a cold cache (a study's workers, the
    suite's) compile it once: one compiles under the signature's lock, the other waits and loads it
    from the cache (``viz3d.compiled._lock_compiles``). Unlocked, both miss the cache and compile (the
    calls start within milliseconds of each other; compiling takes a tenth of a second and more)."""
    (tmp_path / "linked.py").write_text(LINKED, encoding="utf-8")
    outs = _started_together(tmp_path, [RACE, RACE], [{}, {}])
    assert outs == [["0", "1"], ["1", "0"]], "one process compiles (a miss), the other loads (a hit)"


def _started_together(tmp_path, scripts: list[str], fields: list[dict]) -> list[list[str]]:
    """Run each script (formatted with ``folder``, its ``ready`` and the common ``go`` file, and its
    ``fields``) in its own process on one cold cache in ``tmp_path``, released together once all
    are ready; their outputs' words, sorted."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    go = tmp_path / "go"
    ready = [tmp_path / f"ready{k}" for k in range(len(scripts))]
    procs = [subprocess.Popen([sys.executable, "-c", script.format(folder=str(tmp_path), ready=str(r), go=str(go), **f)],
                              env=env, stdout=subprocess.PIPE, text=True) for script, r, f in zip(scripts, ready, fields)]
    deadline = time.monotonic() + 120.0
    while not all(r.exists() for r in ready) and time.monotonic() < deadline:
        time.sleep(0.01)
    go.touch()
    outs = sorted(p.communicate(timeout=300)[0].split() for p in procs)
    assert all(p.returncode == 0 for p in procs)
    return outs


#: Two entries that call one compiled function (as the rigid kernel's entries call ``project``).
SHARING = """
from viz3d.compiled import entry, jit


@jit
def shared(x):
    s = 0.0
    for k in range(3):
        s += x ** k
    return s


@entry
def one(a):
    return shared(a[0])


@entry
def other(a):
    return shared(a[1]) + 1.0
"""
#: Waits until the file ``go`` exists (after writing ``ready``), then calls entry ``name``; prints
#: ``shared``'s cache hits and misses.
SHARE = """
import os, sys, time
sys.path.insert(0, {folder!r})
import numpy as np
import sharing
open({ready!r}, "w").close()
while not os.path.exists({go!r}):
    time.sleep(0.001)
getattr(sharing, {name!r})(np.arange(2.0))
print(sum(sharing.shared.stats.cache_hits.values()), sum(sharing.shared.stats.cache_misses.values()))
"""


def test_processes_compiling_different_entries_compile_their_shared_callee_once(tmp_path):
    """Two processes compiling two entries at once on a cold cache (the suite's two workers warming up
    the rigid and the contact kernel) compile a function both entries call once: the callee too is
    compiled under its signature's lock, and the process that waited for it loads it from the cache
    (``viz3d.compiled._lock_compiles``). Unlocked, both miss the cache and compile it."""
    (tmp_path / "sharing.py").write_text(SHARING, encoding="utf-8")
    outs = _started_together(tmp_path, [SHARE, SHARE], [{"name": "one"}, {"name": "other"}])
    assert outs == [["0", "1"], ["1", "0"]], "one process compiles the callee (a miss), the other loads it (a hit)"


#: Functions inlined into each other (as the kernel's stages are, ``viz3d.compiled.inline``), with
#: branches and loops (many blocks in one scope).
NESTED = """
from viz3d.compiled import entry, inline


@inline
def clipped(x, lo, hi):
    if x < lo:
        return lo
    if x > hi:
        return hi
    return x


@inline
def ramp_sum(a, lo, hi):
    s = 0.0
    for k in range(a.shape[0]):
        if k % 2 == 0:
            s += clipped(a[k], lo, hi)
        else:
            s -= clipped(-a[k], lo, hi)
    return s


@entry
def twice_ramp(a, b):
    t = ramp_sum(a, -0.5, 0.5)
    u = ramp_sum(b, -1.0, 2.0)
    return t * 3.0 + u
"""
#: Compiles ``nested.twice_ramp``; prints the compiled and the Python results and whose
#: ``inline_function`` numba's inliner ran.
INLINED = """
import sys
sys.path.insert(0, {folder!r})
import numpy as np
import nested
from numba.core.inline_closurecall import InlineWorker
a, b = np.linspace(-2.0, 3.0, 11), np.linspace(2.5, -1.5, 7)
compiled = nested.twice_ramp(a, b)
nested.clipped, nested.ramp_sum = nested.clipped.py_func, nested.ramp_sum.py_func  # (not callable from Python)
print(float(compiled).hex(), float(nested.twice_ramp.py_func(a, b)).hex(), InlineWorker.inline_function.__module__)
"""


def _printed(tmp_path, module: str, source: str, script: str) -> list[str]:
    """The words ``script`` (formatted with ``folder``) prints, run in a fresh process with ``source``
    as the module ``module`` in ``tmp_path`` and a cold numba cache there."""
    (tmp_path / f"{module}.py").write_text(source, encoding="utf-8")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    out = subprocess.run([sys.executable, "-c", script.format(folder=str(tmp_path))], env=env, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return out.stdout.split()


def test_the_cheaper_inliner_compiles_nested_inlined_functions_to_the_same_results(tmp_path):
    """numba's inliner, made to copy less once the process first compiles (``viz3d.compiled.
    _cheaper_inlining``), inlines functions into each other as before: the compiled result equals the
    Python one to the bit (the same operations in the same order), and on this numba the change is in
    place (were numba's inliner another, it would be left as it is, and this says so)."""
    compiled_value, python_value, owner = _printed(tmp_path, "nested", NESTED, INLINED)
    assert compiled_value == python_value
    assert owner == "viz3d.compiled", "numba's inliner is not the one _cheaper_inlining was written for"


#: A callee called with different constants (as ``viz3d.kernel.ali3p._branches`` with its modes), and
#: one that cannot be typed without its constant (a tuple of two types indexed by it).
CONSTANTS = """
from viz3d.compiled import entry, jit


@jit
def scaled(x, mode):
    if mode == 0:
        return x
    return x * mode


@jit
def pick(t, i):
    return t[i]


@entry
def modes(x):
    return scaled(x, 0) + scaled(x, 2) + scaled(x, 3) + pick((1, 2.5), 1)
"""
#: Compiles ``constants.modes``; prints how many signatures each callee compiled and both results.
CONSTANTS_RUN = """
import sys
sys.path.insert(0, {folder!r})
import constants
compiled = constants.modes(1.25)
n_scaled, n_pick = len(constants.scaled.signatures), len(constants.pick.signatures)
constants.scaled, constants.pick = constants.scaled.py_func, constants.pick.py_func  # (not callable from Python)
print(n_scaled, n_pick, float(compiled).hex(), float(constants.modes.py_func(1.25)).hex())
"""


def test_a_callee_compiles_once_for_every_constant_its_callers_pass(tmp_path):
    """numba types a constant argument in compiled code as a literal and would compile the callee once
    per constant; viz3d's functions compile once per argument type (``viz3d.compiled.
    _one_signature_per_type``), and one that needs its constant (a tuple indexed by it) still compiles.
    The results equal Python's."""
    n_scaled, n_pick, compiled_value, python_value = _printed(tmp_path, "constants", CONSTANTS, CONSTANTS_RUN)
    assert n_scaled == "1", f"scaled compiled {n_scaled} times, once per constant"
    assert n_pick == "1"
    assert compiled_value == python_value


#: An entry calling a callee that calls another (as the kernel's entries call its stages).
LINKED_CALLEES = """
from viz3d.compiled import entry, jit


@jit
def inner(x, k):
    return x[k] * x[k] + 1.0


@jit
def middle(x):
    s = 0.0
    for k in range(x.shape[0]):
        s += inner(x, k) / (k + 1.0)
    return s


@entry
def outer(x):
    return middle(x) - 2.0 * middle(x)
"""
#: Compiles ``callees.outer``; prints whether its optimized code still calls ``middle`` (not inlined
#: into it), whose code library numba's linker ran, and the compiled and Python results.
LINKED_RUN = """
import sys
sys.path.insert(0, {folder!r})
import numpy as np
import callees
from numba.core.codegen import CPUCodeLibrary
x = np.linspace(-1.0, 2.0, 9)
compiled = callees.outer(x)
(sig,) = callees.outer.signatures
(middle,) = callees.middle.overloads.values()
name = middle.fndesc.mangled_name
ir = callees.outer.inspect_llvm(sig)
calls = any(("call" in line and "@" + name in line) or ("call" in line and '@"' + name + '"' in line)
            for line in ir.splitlines())
callees.inner, callees.middle = callees.inner.py_func, callees.middle.py_func  # (not callable from Python)
print(calls, CPUCodeLibrary.finalize.__module__, float(compiled).hex(), float(callees.outer.py_func(x)).hex())
"""


def test_callees_are_linked_into_their_caller_after_it_is_optimized(tmp_path):
    """Each compiled callee is optimized once, in its own library, and linked into its caller after
    the caller is optimized (``viz3d.compiled._link_optimized_callees``): the caller's optimized code
    calls it instead of holding a copy optimized again. The results equal Python's."""
    calls, owner, compiled_value, python_value = _printed(tmp_path, "callees", LINKED_CALLEES, LINKED_RUN)
    assert owner == "viz3d.compiled", "numba's code library is not the one _link_optimized_callees was written for"
    assert calls == "True", "the caller's code holds its callee inlined: it was linked before optimizing"
    assert compiled_value == python_value
