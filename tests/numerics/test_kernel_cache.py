"""The on-disk cache of the compiled kernel is keyed on every source file with compiled code: an
edit of one element's piece (say a contact's gap) must recompile the kernel functions that inline it,
whose own file did not change (numba alone keys a function on its own file)."""

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
