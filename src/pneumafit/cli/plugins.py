"""Physics parts from outside the package, for the command line.

A heat law or an effect written outside the package (``HeatLaw``/``Effect``
with its ``@njit`` law, docs/effects.md "An effect from outside the
package") is registered by importing the module that defines it. From
Python, importing it is enough. The command line imports, before any
command runs:

- every entry point of the group ``pneumafit.parts`` of the installed
  distributions (a plug-in package declares
  ``[project.entry-points."pneumafit.parts"] name = "my_package.parts"``);
- each file or module named by ``pneumafit --parts PATH_OR_MODULE``
  (repeatable) or by the environment variable ``PNEUMAFIT_PARTS``
  (separated by the path separator, ``:`` on POSIX).

``--parts`` is copied into ``PNEUMAFIT_PARTS``, so that processes the
command starts (``fit-many``'s workers) load the same parts. A name that
cannot be loaded is an input error naming it and the reason (exit 2).
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import sys
from collections.abc import Sequence
from importlib.metadata import entry_points
from pathlib import Path
from types import ModuleType

from rich.table import Table

from pneumafit.errors import PneumafitInputError

__all__ = ["ENTRY_POINT_GROUP", "ENVIRONMENT_VARIABLE", "load_parts", "parts_tables"]

#: Entry-point group of plug-in packages that register parts on import.
ENTRY_POINT_GROUP = "pneumafit.parts"
#: Environment variable naming files or modules of parts (os.pathsep-separated).
ENVIRONMENT_VARIABLE = "PNEUMAFIT_PARTS"

_LOADED: dict[str, ModuleType] = {}


def _load_one(name: str, where: str) -> str:
    """Import a file (``*.py`` or an existing path) or a module by name, once per process.

    Returns the name it is loaded under: a file's absolute path (a worker
    may start elsewhere), or the module's name.
    """
    path = Path(name).expanduser()
    is_file = name.endswith(".py") or path.is_file()
    key = str(path.resolve()) if is_file else name
    if key in _LOADED:
        return key
    try:
        if is_file:
            if not path.is_file():
                raise FileNotFoundError(f"no such file: {os.fspath(path)}")
            digest = hashlib.sha256(key.encode()).hexdigest()[:12]
            module_name = f"pneumafit_parts_{path.stem}_{digest}"
            spec = importlib.util.spec_from_file_location(module_name, path)
            if spec is None or spec.loader is None:
                raise ImportError(f"not a Python file: {os.fspath(path)}")
            module = importlib.util.module_from_spec(spec)
            sys.modules[module_name] = module
            try:
                spec.loader.exec_module(module)
            except BaseException:
                sys.modules.pop(module_name, None)
                raise
        else:
            module = importlib.import_module(name)
    except PneumafitInputError as exc:  # a part refused by its registry
        raise PneumafitInputError(f"{where} {name!r}: {exc}") from None
    except (ImportError, OSError, SyntaxError) as exc:
        raise PneumafitInputError(
            f"{where} {name!r}: expected a Python file or an importable module that registers "
            f"parts (pneumafit.models.parts), found {type(exc).__name__}: {exc}"
        ) from None
    _LOADED[key] = module
    return key


def load_parts(names: Sequence[str] = ()) -> list[str]:
    """Import the parts' modules: entry points, ``names``, then ``PNEUMAFIT_PARTS``.

    Parameters
    ----------
    names : sequence of str
        Files or module names (``--parts``); added to ``PNEUMAFIT_PARTS`` in
        this process's environment.

    Returns
    -------
    list of str
        What is loaded: entry points as ``group:name``, then files by
        absolute path and modules by name.

    Raises
    ------
    PneumafitInputError
        A file or module that cannot be imported, or whose parts a registry
        refuses, naming it.
    """
    loaded = []
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        key = f"{ENTRY_POINT_GROUP}:{ep.name}"
        if key not in _LOADED:
            try:
                _LOADED[key] = ep.load()
            except Exception as exc:  # a third-party package: name it, whatever it raised
                raise PneumafitInputError(
                    f"entry point {ep.name!r} of group {ENTRY_POINT_GROUP} ({ep.value}): cannot "
                    f"be loaded: {type(exc).__name__}: {exc}"
                ) from None
        loaded.append(key)
    given = [_load_one(name, "option --parts") for name in names]
    env = [n for n in os.environ.get(ENVIRONMENT_VARIABLE, "").split(os.pathsep) if n]
    named = [_load_one(name, f"environment variable {ENVIRONMENT_VARIABLE}:") for name in env]
    keys = list(dict.fromkeys([*named, *given]))
    if keys:
        os.environ[ENVIRONMENT_VARIABLE] = os.pathsep.join(keys)
    return [*loaded, *keys]


def parts_tables() -> list[Table]:
    """The registered parts as tables (``pneumafit parts``): built-in and loaded.

    Returns
    -------
    list of rich.table.Table
        Heat laws, valve laws, friction laws, effects, and the parameters
        registered from outside the package (when there are any).
    """
    from pneumafit.models import layout, parts

    def kernel_of(part: object, built_in: bool) -> str:
        if getattr(part, "kernel", None) is not None:
            # with C code too, the FMU export takes it (docs/export.md)
            c = " and C (FMU)" if getattr(part, "c_code", None) is not None else ""
            if getattr(part, "stuck", False):
                return "its own (@njit), sliding force in the switch model's stuck mode"
            if getattr(part, "state_rate", None) is None:
                return f"its own (@njit){c}"
            slots = getattr(part, "states", ()) or (layout.X_Z,)
            names = ", ".join(layout.STATE_NAMES[i] for i in slots)
            return f"its own (@njit){c}, state {names}"
        return "built in" if built_in else "none (Python side only)"

    heat = Table(title="heat laws (--model)")
    for col in ("name", "code", "parameters", "kernel code", "description"):
        heat.add_column(col)
    for law in parts.HEAT_LAWS.values():
        own = kernel_of(law, law.code in parts.KERNEL_HEAT_CODES)
        heat.add_row(law.name, str(law.code), ", ".join(law.parameters), own, law.description)
    tables = [heat]
    for title, registry, codes in (
        ("valve laws (--valve)", parts.VALVE_LAWS, parts.KERNEL_VALVE_CODES),
        ("friction laws (--friction)", parts.FRICTION_LAWS, parts.KERNEL_FRICTION_CODES),
    ):
        table = Table(title=title)
        for col in ("name", "code", "kernel code", "description"):
            table.add_column(col)
        for law in registry.values():
            table.add_row(law.name, str(law.code), kernel_of(law, law.code in codes),
                          law.description)  # fmt: skip
        tables.append(table)
    effects = Table(title="effects (discovery's catalog, --effect)")
    for col in ("name", "kernel code", "options", "principal", "parameters", "description"):
        effects.add_column(col)
    for effect in parts.EFFECTS.values():
        where = f"slot {effect.slot}" if effect.slot is not None else kernel_of(effect, False)
        options = ", ".join(str(v) for v in sorted(effect.options))
        effects.add_row(effect.name, where, options, effect.principal,
                        ", ".join(effect.parameters), effect.description)  # fmt: skip
    tables.append(effects)
    registered = layout.PARAMETER_SPECS[layout.NP :]
    if registered:
        table = Table(title="parameters registered from outside the package")
        for col in ("name", "unit", "default", "bounds", "group", "description"):
            table.add_column(col)
        for spec in registered:
            bounds = f"[{spec.lower:g}, {spec.upper:g}]"
            table.add_row(spec.name, spec.unit, f"{spec.default:g}", bounds, spec.group,
                          spec.description)  # fmt: skip
        tables.append(table)
    return tables
