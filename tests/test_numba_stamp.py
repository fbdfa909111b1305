"""The package-wide numba cache stamp (pneumafit.numba_stamp).

A cached compiled function holds the code of the compiled functions it calls;
numba only checks the caller's own file. These tests check that every
compiled function of the package gets the locator whose stamp also hashes
every compiled source file, so that a change to a callee's file invalidates
its callers' caches.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from numba.core import caching

from pneumafit import numba_stamp
from pneumafit.models import kernel
from pneumafit.simulation import reference, sampled


def _locator(dispatcher) -> object:
    return dispatcher._cache._impl.locator


def test_every_compiled_module_is_hashed_and_uses_the_wrapper() -> None:
    names = {p.relative_to(numba_stamp._ROOT).as_posix() for p in numba_stamp.compiled_sources()}
    assert {"models/kernel.py", "simulation/sampled.py", "simulation/reference.py",
            "physics/valve.py"} <= names  # fmt: skip
    for path in numba_stamp.compiled_sources():
        text = path.read_text(encoding="utf-8")
        assert "from numba import njit" not in text, path  # numba's own njit skips the stamp
        assert "from pneumafit.numba_stamp import njit" in text, path


def test_package_functions_carry_the_package_stamp() -> None:
    """A caller in one file (reference._evaluate, sampled._advance) and
    a callee in another (kernel.rhs) share the package stamp; changing it
    (as editing any compiled file does) changes every stamp."""
    for fn in (kernel.derive, reference._evaluate, sampled._advance):
        loc = _locator(fn)
        assert getattr(type(loc), "_pneumafit", False)
        _own, package = loc.get_source_stamp()
        assert package == numba_stamp.package_stamp()
    before = _locator(reference._evaluate).get_source_stamp()
    saved = list(numba_stamp._STAMP)
    try:
        numba_stamp._STAMP[:] = [b"another tree"]
        after = _locator(reference._evaluate).get_source_stamp()
    finally:
        numba_stamp._STAMP[:] = saved
    assert after != before and after[0] == before[0]


def test_install_is_idempotent_and_leaves_other_files_to_numba(tmp_path: Path) -> None:
    assert numba_stamp.install() and numba_stamp.install()
    ours = [c for c in caching.CacheImpl._locator_classes if getattr(c, "_pneumafit", False)]
    assert len(ours) == 1
    other = tmp_path / "other.py"
    other.write_text("def f():\n    return 1\n")
    namespace: dict = {}
    exec(compile(other.read_text(), str(other), "exec"), namespace)
    assert ours[0].from_function(namespace["f"], str(other)) is None


def test_the_stamp_hashes_names_and_contents(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "a.py").write_text("@njit(cache=True)\ndef f(): pass\n")
    (tmp_path / "b.py").write_text("x = 1\n")
    monkeypatch.setattr(numba_stamp, "_ROOT", tmp_path)
    monkeypatch.setattr(numba_stamp, "_STAMP", [])
    assert [p.name for p in numba_stamp.compiled_sources()] == ["a.py"]
    first = numba_stamp.package_stamp()
    (tmp_path / "a.py").write_text("@njit(cache=True)\ndef f(): return 2\n")
    numba_stamp._STAMP.clear()
    assert numba_stamp.package_stamp() != first


def test_the_stamp_covers_the_constants_compiled_code_reads(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A module without compiled functions whose constants compiled code
    freezes (as ``models/layout.py``: ``NX``, the parameter indices) is in
    the stamp, through an import of an import within the model and physics
    layers; an import of another layer is not followed. Editing the
    constants' file changes the stamp: before, a layout-only edit left every
    cached kernel running the old layout."""
    root = tmp_path / "pkg"
    (root / "models").mkdir(parents=True)
    (root / "other").mkdir()
    (root / "kern.py").write_text(
        "from pkg.models import layout\nfrom pkg.other.cli import X\n"
        "@njit(cache=True)\ndef f(): return layout.N\n"
    )
    (root / "models" / "layout.py").write_text("from pkg.models.specs import SPECS\nN = 16\n")
    (root / "models" / "specs.py").write_text("SPECS = (1, 2)\n")
    (root / "other" / "cli.py").write_text("X = 1\n")
    monkeypatch.setattr(numba_stamp, "_ROOT", root)
    monkeypatch.setattr(numba_stamp, "_STAMP", [])
    names = {p.relative_to(root).as_posix() for p in numba_stamp.stamped_sources()}
    assert names == {"kern.py", "models/layout.py", "models/specs.py"}
    first = numba_stamp.package_stamp()
    (root / "models" / "layout.py").write_text("from pkg.models.specs import SPECS\nN = 18\n")
    numba_stamp._STAMP.clear()
    assert numba_stamp.package_stamp() != first
