"""The on-disk cache of the compiled kernel is keyed on every source file with compiled code: an
edit of one element's piece (say a contact's gap) must recompile the kernel functions that inline it,
whose own file did not change (numba alone keys a function on its own file). A load from the cache
does only what a call from Python needs."""

import os
import subprocess
import sys

import pytest

numba = pytest.importorskip("numba")

from viz3d import compiled  # noqa: E402
from viz3d.contact import contacts  # noqa: E402
from viz3d.kernel import field, stepping  # noqa: E402


@pytest.mark.parametrize("fn", [field.evaluate, field.gaps, stepping.advance], ids=lambda f: f.py_func.__name__)
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
