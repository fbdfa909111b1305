"""Keep numba's on-disk cache consistent across the package's compiled modules.

numba caches each ``@njit(cache=True)`` function under a hash of the file
that defines it, and a cached function holds the machine code of every
compiled function it calls, from whatever file. When a callee's file
changes (``git pull`` in an editable install, an edit) and the caller's
does not, numba keeps loading the caller's cache and runs the old callee.
Measured: after the valve law gained two parameters (which shifts every
later index of the parameter vector) the reference solver's compiled
right-hand side (``simulation/reference.py``, unchanged) still ran the old
kernel, and a 3-s charge ended 110 kPa away from the kernel's own run.

:func:`install` (called by :func:`njit`, the decorator every compiled
module of the package uses instead of numba's) gives numba a cache locator
for the package's own files whose freshness stamp is the defining file's
(numba's) together with one hash of every compiled source file of the
package and of the model and physics modules they import (the state
layout, the parameter table: constants the compiled code freezes;
:func:`stamped_sources`): a change to any of them
invalidates the cache of all of them (one recompilation, about a minute;
``python -m pneumafit.warmup`` does it ahead). Other packages' functions
keep numba's own locators. The locator list is numba's private API
(``numba.core.caching.CacheImpl._locator_classes``, numba 0.58-0.68); where
it is missing, nothing is installed and numba's behaviour is unchanged.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path
from typing import Any

__all__ = ["compiled_sources", "install", "njit", "package_stamp", "stamped_sources"]

#: The package directory.
_ROOT = Path(__file__).resolve().parent
#: What marks a module with cached compiled functions.
_MARK = re.compile(r"njit\([^)]*cache=True")
_STAMP: list[bytes] = []
#: An import statement: ``import a.b`` or ``from a.b import c, d`` (names in
#: parentheses over several lines too); :func:`stamped_sources` keeps the
#: package's.
_IMPORT = re.compile(
    r"^[ \t]*(?:import[ \t]+(?P<plain>[\w.]+(?:[ \t]*,[ \t]*[\w.]+)*)"
    r"|from[ \t]+(?P<module>[\w.]+)[ \t]+import[ \t]+(?P<names>\([^)]*\)|[^\n#]+))",
    re.MULTILINE,
)
#: Packages whose modules' constants compiled code reads (:func:`stamped_sources`).
_CONSTANT_LAYERS = ("models", "physics")


def compiled_sources(root: Path | None = None) -> list[Path]:
    """The package's source files that define cached numba functions.

    Parameters
    ----------
    root : Path, optional
        The package directory; this module's own by default.

    Returns
    -------
    list of Path
        Sorted; this module is not one of them.
    """
    base = _ROOT if root is None else root
    here = Path(__file__).resolve()
    out = []
    for path in sorted(base.rglob("*.py")):
        if path.resolve() == here:
            continue
        try:
            if _MARK.search(path.read_text(encoding="utf-8")):
                out.append(path)
        except OSError:
            continue
    return out


def stamped_sources(root: Path | None = None) -> list[Path]:
    """:func:`compiled_sources` and the modules of the model and physics
    layers (``models/``, ``physics/``) they import, directly or through
    another such module: compiled code freezes the module-level constants it
    reads (the state layout's ``NX``, the parameter indices of
    ``models/layout.py``, which defines no compiled function, built from the
    registered parts), so their files belong in the stamp too. Imports of
    other layers are not followed (their constants are not the kernel's, and
    an edit there would recompile everything). ``root`` and the result as
    :func:`compiled_sources` (this module is not in those layers).
    """
    base = _ROOT if root is None else root
    seen: set[Path] = set()
    todo = list(compiled_sources(base))
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            continue
        for match in _IMPORT.finditer(text):  # a regular expression: ast costs 0.1 s here
            if match.group("plain"):
                names = [n.split(" as ")[0].strip() for n in match.group("plain").split(",")]
            else:
                module = match.group("module")
                listed = re.sub(r"#[^\n]*", "", match.group("names")).strip("()")
                names = [module] + [
                    f"{module}.{n.split(' as ')[0].strip()}" for n in listed.split(",") if n.strip()
                ]
            for name in names:
                parts = name.split(".")
                if parts[0] != base.name:
                    continue
                if len(parts) < 2 or parts[1] not in _CONSTANT_LAYERS:
                    continue
                stem = base.joinpath(*parts[1:])
                for candidate in (stem.with_suffix(".py"), stem / "__init__.py"):
                    if candidate.is_file() and candidate not in seen:
                        todo.append(candidate)
    return sorted(seen)


def package_stamp() -> bytes:
    """SHA-256 over the names and contents of :func:`stamped_sources` (computed once)."""
    if not _STAMP:
        digest = hashlib.sha256()
        for path in stamped_sources():
            digest.update(path.relative_to(_ROOT).as_posix().encode())
            digest.update(path.read_bytes())
        _STAMP.append(digest.digest())
    return _STAMP[0]


def _in_package(py_file: str) -> bool:
    try:
        return Path(py_file).resolve().is_relative_to(_ROOT)
    except (OSError, ValueError):
        return False


def install() -> bool:
    """Put the package-wide locator first in numba's list (idempotent).

    Must run before the package's first ``@njit(cache=True)`` decorator
    (:func:`njit` calls it): numba picks a function's locator when it is
    decorated.

    Returns
    -------
    bool
        True when the locator is (now) installed.
    """
    try:
        from numba.core import caching
    except ImportError:  # pragma: no cover - numba is a dependency
        return False
    impl = getattr(caching, "CacheImpl", None)
    classes = getattr(impl, "_locator_classes", None)
    base = getattr(caching, "_CacheLocator", None)
    if not isinstance(classes, list) or base is None:
        return False
    if any(getattr(c, "_pneumafit", False) for c in classes):
        return True
    fallbacks = list(classes)

    class PackageLocator(base):  # type: ignore[misc, valid-type]
        """numba's locator for a package file, with the package-wide stamp."""

        _pneumafit = True

        def __init__(self, inner: Any) -> None:
            self._inner = inner

        def ensure_cache_path(self) -> None:
            self._inner.ensure_cache_path()

        def get_cache_path(self) -> str:
            return self._inner.get_cache_path()

        def get_source_stamp(self) -> Any:
            return (self._inner.get_source_stamp(), package_stamp())

        def get_disambiguator(self) -> str:
            return self._inner.get_disambiguator()

        @classmethod
        def from_function(cls, py_func: Any, py_file: str) -> Any:
            if not _in_package(py_file):
                return None
            for fallback in fallbacks:
                inner = fallback.from_function(py_func, py_file)
                if inner is not None:
                    return cls(inner)
            return None

    classes.insert(0, PackageLocator)
    return True


def njit(*args: Any, **kwargs: Any) -> Any:
    """``numba.njit``, after :func:`install`: the package's compiled modules
    decorate with this one, so that their caches carry the package stamp."""
    install()
    from numba import njit as numba_njit

    return numba_njit(*args, **kwargs)
