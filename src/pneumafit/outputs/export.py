"""Parameter sets and gain schedules exported for controllers.

One document, four encodings (JSON, YAML, C header, MATLAB .mat). The schema,
``pneumafit-controller-export`` version 1 (all values SI)::

    format, version                  "pneumafit-controller-export", 1
    source      {file, model}        where the parameters came from
    parameters  {NAME: {value, unit, std, interval_90, fixed}}
                                     every model parameter; std/interval from a
                                     fit.json where it has them, else null
    design      {order, w0, lambda_e, poles: [[re, im], ...]}
    states      ["y", "v", "p_N", "p_P", ("T_N", "T_P")]
    state_units ["m", "m/s", "Pa", "Pa", ("K", "K")]
    input       "u = u_P (V); u_N = -u"
    law         "u = u_e - K (x - x_e)"
    grid        positions [m] (n)
                u_e [V], p_P_e [Pa], p_N_e [Pa], T_e [K]   (n each)
                A (n, order, order), B (n, order), K (n, order)

Positions with no equilibrium are left out of the grid (and listed under
``skipped``). The C header declares ``static const double`` arrays with
17 significant digits (exact double round trip) and ``#define`` constants for
the sizes and the parameters.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np

from pneumafit.analysis import itae_poles, linearize, place
from pneumafit.fileio import atomic_path, write_text_atomic
from pneumafit.models.layout import PARAMETER_NAMES, SPECS
from pneumafit.models.parameters import parameter_dict, parameter_vector

FORMATS = ("json", "yaml", "c", "mat")
STATE_UNITS = ("m", "m/s", "Pa", "Pa", "K", "K")


def build_export(
    details: dict[str, dict],
    *,
    model: str,
    source: str,
    positions: np.ndarray,
    order: int,
    w0: float,
    lambda_e: float,
    valve: str = "iso6358",
) -> dict:
    """The export document (see the module docstring).

    Parameters
    ----------
    details : dict
        Parameters given by the source, ``{name: {value, std, interval_90,
        fixed}}`` (SI); every other model parameter takes its default.
    model : str
        Model structure of the source.
    source : str
        Source file name, for provenance.
    positions : ndarray
        Grid of piston positions (m).
    order : {4, 6}
        Design model: polytropic (4) or heat model (6).
    w0 : float
        ITAE frequency scale (rad/s).
    lambda_e : float
        Nominal lambda of the 6th-order design (W/m^2/K).
    valve : {"iso6358", "map"}
        Valve law of the source (a map's knot tables are among the
        parameters, and the equilibria and B use them).
    """
    vec = parameter_vector({name: d["value"] for name, d in details.items()})
    values = parameter_dict(vec)
    params = {}
    for name in PARAMETER_NAMES:
        d = details.get(name, {})
        params[name] = {
            "value": values[name],
            "unit": SPECS[name].unit,
            "std": d.get("std"),
            "interval_90": d.get("interval_90"),
            "fixed": d.get("fixed", name not in details),
        }
    poles = itae_poles(order, w0)
    grid: dict[str, list] = {k: [] for k in ("positions", "u_e", "p_P_e", "p_N_e", "T_e", "A",
                                            "B", "K")}  # fmt: skip
    skipped = []
    for y in positions:
        try:
            lin = linearize(vec, float(y), order=order, lambda_e=lambda_e, valve=valve)
        except ValueError as exc:
            skipped.append({"y": float(y), "reason": str(exc)})
            continue
        eq = lin.equilibrium
        grid["positions"].append(float(y))
        grid["u_e"].append(eq.u)
        grid["p_P_e"].append(eq.p_P)
        grid["p_N_e"].append(eq.p_N)
        grid["T_e"].append(eq.T)
        grid["A"].append(lin.A.tolist())
        grid["B"].append(lin.B.ravel().tolist())
        grid["K"].append(place(lin, poles)[0].tolist())
    return _plain(
        {
            "format": "pneumafit-controller-export",
            "version": 1,
            "source": {"file": source, "model": model, "valve": valve},
            "parameters": params,
            "design": {
                "order": order,
                "w0": w0,
                "lambda_e": lambda_e if order == 6 else None,
                "poles": [[float(p.real), float(p.imag)] for p in poles],
            },
            "states": ["y", "v", "p_N", "p_P", "T_N", "T_P"][:order],
            "state_units": list(STATE_UNITS[:order]),
            "input": "u = u_P (V); u_N = -u",
            "law": "u = u_e - K (x - x_e)",
            "grid": grid,
            "skipped": skipped,
        }
    )


def _plain(value):
    """Plain Python values (no numpy scalars), so every encoder accepts them."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _c_number(x: float) -> str:
    return repr(float(x)) if np.isfinite(x) else "0.0 /* not finite */"


def _c_array(name: str, values: np.ndarray) -> str:
    values = np.asarray(values, dtype=float)
    dims = "".join(f"[{n}]" for n in values.shape)

    def body(a: np.ndarray, indent: str) -> str:
        if a.ndim == 1:
            return "{" + ", ".join(f"{v:.17g}" for v in a) + "}"
        inner = f",\n{indent}  ".join(body(sub, indent + "  ") for sub in a)
        return "{\n" + indent + "  " + inner + "\n" + indent + "}"

    return f"static const double {name}{dims} PF_UNUSED = {body(values, '')};\n"


def _c_header(doc: dict) -> str:
    grid = doc["grid"]
    n, order = len(grid["positions"]), doc["design"]["order"]
    lines = [
        "/* pneumafit controller export (format pneumafit-controller-export v1).",
        f" * Source: {doc['source']['file']} ({doc['source']['model']} model).",
        f" * Design: order {order}, ITAE poles scaled by w0 = {doc['design']['w0']:g} rad/s.",
        f" * Law: {doc['law']}; {doc['input']}.",
        f" * States: {', '.join(f'{s} [{u}]' for s, u in zip(doc['states'], doc['state_units'], strict=True))}.",  # noqa: E501
        " * All values SI. Generated file: do not edit. */",
        "#ifndef PNEUMAFIT_EXPORT_H",
        "#define PNEUMAFIT_EXPORT_H",
        "",
        "/* tables a translation unit may not use all of: no unused-variable warnings */",
        "#if defined(__GNUC__) || defined(__clang__)",
        "#define PF_UNUSED __attribute__((unused))",
        "#else",
        "#define PF_UNUSED",
        "#endif",
        "",
        f"#define PF_N_POSITIONS {n}",
        f"#define PF_N_STATES {order}",
        "",
    ]
    for name, p in doc["parameters"].items():
        macro = "PF_" + re.sub(r"[^A-Za-z0-9]", "_", name).upper()
        note = f"{p['unit'] or '-'}"
        if p["interval_90"] is not None:
            note += f", 90% interval [{p['interval_90'][0]:.6g}, {p['interval_90'][1]:.6g}]"
        lines.append(f"#define {macro} ({_c_number(p['value'])}) /* {note} */")
    lines.append("")
    text = "\n".join(lines) + "\n"
    text += _c_array("pf_positions", np.array(grid["positions"]).reshape(n))
    for key in ("u_e", "p_P_e", "p_N_e", "T_e"):
        text += _c_array(f"pf_{key}", np.array(grid[key]).reshape(n))
    text += _c_array("pf_A", np.array(grid["A"]).reshape(n, order, order))
    text += _c_array("pf_B", np.array(grid["B"]).reshape(n, order))
    text += _c_array("pf_K", np.array(grid["K"]).reshape(n, order))
    text += "\n#endif /* PNEUMAFIT_EXPORT_H */\n"
    return text


def _mat_safe(doc: dict) -> dict:
    """The document as MATLAB-friendly nested dicts (None -> NaN)."""

    def conv(v):
        if v is None:
            return np.nan
        if isinstance(v, dict):
            return {k: conv(x) for k, x in v.items()}
        if isinstance(v, list) and v and isinstance(v[0], dict):
            return np.array([json.dumps(x) for x in v], dtype=object)
        if isinstance(v, list):
            arr = np.array(v, dtype=object if any(isinstance(x, str) for x in v) else float)
            return arr
        return v

    return {k: conv(v) for k, v in doc.items() if k != "skipped"}


def write_export(doc: dict, path: str | os.PathLike[str], fmt: str) -> Path:
    """Write the export in ``fmt`` (json, yaml, c, mat), atomically."""
    target = Path(path)
    if fmt not in FORMATS:
        raise ValueError(f"export: format: expected one of {', '.join(FORMATS)}, found {fmt!r}")
    if fmt == "json":
        write_text_atomic(target, json.dumps(doc, indent=2) + "\n")
    elif fmt == "yaml":
        import yaml

        write_text_atomic(target, yaml.safe_dump(doc, sort_keys=False))
    elif fmt == "c":
        write_text_atomic(target, _c_header(doc))
    else:
        from scipy.io import savemat

        with atomic_path(target) as tmp:
            with open(tmp, "wb") as stream:
                savemat(stream, {"pneumafit": _mat_safe(doc)}, long_field_names=True)
    return target


def read_export(path: str | os.PathLike[str]) -> dict:
    """Read a JSON or YAML export back (round trips)."""
    text = Path(path).read_text(encoding="utf-8")
    if str(path).endswith((".yaml", ".yml")):
        import yaml

        return yaml.safe_load(text)
    return json.loads(text)
