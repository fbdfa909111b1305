"""The validated controller exported for controllers and rigs.

One document, five encodings: JSON, YAML, a C header with its controller
source (``controller.h`` and ``controller.c``), a MATLAB .mat file and a CSV
of the gain schedule. The schema, ``pneumafit-controller-export`` version 2
(all values SI; version 1, the full-order ITAE schedule without the
compensation, is still read by :func:`read_export`)::

    format, version   "pneumafit-controller-export", 2
    source            {file, model, valve}     where the parameters came from
    parameters        {NAME: {value, unit, std, interval_90, fixed}}
    design            {order, placement, w0, w0_rule, compensation, lambda_e,
                       operating_position, validated, description}
                      validated: true when this is the design the closed-loop
                      stage ran (same order, placement, w0 and compensation)
    controller        {law, schedule, umax, period, deadband_amplitude}
    states            ["y", "v", "p_N", "p_P", ("T_N", "T_P")]
    state_units       ["m", "m/s", "Pa", "Pa", ("K", "K")]
    input             the input of A, B: v, the controller output before the
                      compensation (u without compensation)
    linear_model      {inputs, outputs, C (n, n) = I, D (n, 1) = 0}
    grid              positions [m] (n breakpoints)
                      u_e [V], v_e [V], p_P_e, p_N_e [Pa], T_e [K],
                      deadband_width [V]                      (n each)
                      A (n, order, order), B (n, order) (input v),
                      B_valve (n, order) (input u), K (n, order),
                      poles (n, order, 2) [1/s, as re, im]
    skipped           [{y, reason}]  positions left out of the grid

The law (:mod:`pneumafit.analysis.controller`), every sampling period:
interpolate K, v_e, the equilibrium and w linearly in the measured position
(clamped at the grid's ends), v = v_e - K (x - x_e) with x_e's position the
reference, u = v + a tanh(v / w), u_P = clip(u, -umax, umax), u_N = -u_P.
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pneumafit.analysis.controller import design_schedule
from pneumafit.errors import PneumafitInputError
from pneumafit.fileio import atomic_path, write_text_atomic
from pneumafit.models.layout import PARAMETER_NAMES, SPECS
from pneumafit.models.parameters import parameter_dict, parameter_vector

FORMATS = ("json", "yaml", "c", "mat", "csv")
VERSION = 2
READABLE_VERSIONS = (1, 2)
STATE_NAMES = ("y", "v", "p_N", "p_P", "T_N", "T_P")
STATE_UNITS = ("m", "m/s", "Pa", "Pa", "K", "K")
GAIN_UNITS = ("V/m", "V s/m", "V/Pa", "V/Pa", "V/K", "V/K")

LAW = (
    "v = v_e(y) - K(y) (x - x_e), x_e = [y_ref, 0, p_N_e(y), p_P_e(y), T_e(y), T_e(y)]; "
    "u = v + a tanh(v / w(y)) (u = v when w = 0); u_P = clip(u, -umax, umax); u_N = -u_P"
)
SCHEDULE = (
    "K, v_e, p_N_e, p_P_e, T_e and w interpolated linearly in the measured position y "
    "between the grid's breakpoints, held at the end values outside the grid; the "
    "command is computed every period and held in between"
)


def with_operating_position(positions: Sequence[float], y: float | None) -> np.ndarray:
    """The grid with the operating position y (m) as a breakpoint: the grid
    point nearest it is moved there when within 1 um, else y is inserted."""
    grid = np.sort(np.asarray(positions, dtype=float))
    if y is None:
        return grid
    if grid.size and np.min(np.abs(grid - y)) < 1e-6:
        grid[np.argmin(np.abs(grid - y))] = y
        return grid
    return np.sort(np.append(grid, y))


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
    placement: str = "dominant",
    compensate: bool = True,
    umax: float = 10.0,
    operating_position: float | None = None,
    w0_rule: str = "given",
    validated: bool = False,
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
        Grid of piston positions (m), the schedule's breakpoints.
    order : {4, 6}
        Design model: polytropic (4) or heat model (6).
    w0 : float
        ITAE frequency scale (rad/s).
    lambda_e : float
        Nominal lambda of the 6th-order design (W/m^2/K).
    valve : {"iso6358", "map"}
        Valve law of the source.
    placement : {"dominant", "itae"}
        Pole choice (:func:`pneumafit.analysis.closed_loop.design_poles`).
    compensate : bool
        Dead-band compensation before the valve.
    umax : float
        Command limit (V).
    operating_position : float, optional
        The closed-loop stage's design position (m), made a breakpoint so
        that the schedule there is exactly the validated design.
    w0_rule : str
        How w0 was chosen, in words (stored as is).
    validated : bool
        True when this design is the one the closed-loop stage ran.
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
    grid_y = with_operating_position(positions, operating_position)
    law, designs, skipped = design_schedule(
        vec, grid_y, order=order, w0=w0, placement=placement, compensate=compensate,
        lambda_e=lambda_e, valve=valve, umax=umax,
    )  # fmt: skip
    grid: dict[str, list] = {k: [] for k in (
        "positions", "u_e", "v_e", "p_P_e", "p_N_e", "T_e", "deadband_width", "A", "B",
        "B_valve", "K", "poles")}  # fmt: skip
    for d, width in zip(designs, law.deadband_width, strict=True):
        eq = d.model.equilibrium
        slope = d.compensation.slope(d.model.v_e) if d.compensation else 1.0
        grid["positions"].append(float(eq.y))
        grid["u_e"].append(eq.u)
        grid["v_e"].append(d.model.v_e)
        grid["p_P_e"].append(eq.p_P)
        grid["p_N_e"].append(eq.p_N)
        grid["T_e"].append(eq.T)
        grid["deadband_width"].append(width)
        grid["A"].append(d.model.A.tolist())
        grid["B"].append(d.model.B.ravel().tolist())
        grid["B_valve"].append((d.model.B.ravel() / slope).tolist())
        grid["K"].append(d.gain.tolist())
        grid["poles"].append([[float(p.real), float(p.imag)] for p in d.poles])
    c_matrix, d_matrix = designs[0].model.output_matrices()
    states = list(STATE_NAMES[:order])
    kind = "compensated" if law.deadband > 0 else "uncompensated"
    input_text = "u = u_P (V); u_N = -u"
    if law.deadband > 0:
        input_text = ("v (V): the controller output before the dead-band compensation; "
                      "u = u_P = c(v) at the valve, u_N = -u_P")  # fmt: skip
    description = (
        f"order {order} ({'heat model, eq. 13' if order == 6 else 'polytropic, eq. 14'}), "
        f"{placement} placement at w0 = {w0:.6g} rad/s, {kind}: "
        + ("the design the closed-loop stage validated on the nonlinear model"
           if validated else "a user's choice, not the design the closed-loop stage validated")
    )  # fmt: skip
    return _plain(
        {
            "format": "pneumafit-controller-export",
            "version": VERSION,
            "source": {"file": source, "model": model, "valve": valve},
            "parameters": params,
            "design": {
                "order": order,
                "placement": placement,
                "w0": w0,
                "w0_rule": w0_rule,
                "compensation": bool(law.deadband > 0),
                "lambda_e": lambda_e if order == 6 else None,
                "operating_position": operating_position,
                "validated": bool(validated),
                "description": description,
            },
            "controller": {
                "law": LAW,
                "schedule": SCHEDULE,
                "umax": law.umax,
                "period": law.period,
                "deadband_amplitude": law.deadband,
                "gain_units": list(GAIN_UNITS[:order]),
            },
            "states": states,
            "state_units": list(STATE_UNITS[:order]),
            "input": input_text,
            "law": LAW,
            "linear_model": {
                "inputs": [designs[0].model.input_name],
                "outputs": states,
                "C": c_matrix.tolist(),
                "D": d_matrix.tolist(),
                "note": "deviations from the grid point's equilibrium: dx/dt = A dx + B dv, "
                "dy = C dx + D dv",
            },
            "grid": grid,
            "skipped": skipped,
        }
    )


def export_document(
    fit: str | os.PathLike[str],
    *,
    order: int = 6,
    placement: str | None = None,
    w0: float | None = None,
    compensate: bool | None = None,
    positions: Sequence[float] | None = None,
    lambda_e: float | None = None,
    umax: float | None = None,
    position: float | None = None,
    step: float = 0.03,
    closed_loop: str | os.PathLike[str] | None = None,
) -> dict:
    """The export document of a fit.json or parameter file.

    By default the design is the one ``pneumafit closed-loop`` runs with its
    defaults: dominant placement, dead-band compensation, w0 from
    :func:`pneumafit.analysis.closed_loop.largest_w0` (orders 4 and 6, a
    ``step`` m step within 90 % of ``umax``), at half stroke. ``closed_loop``
    (a ``closed_loop.json``) takes w0, placement, compensation, lambda_e,
    umax and the position from what that run used. Any option given
    explicitly overrides; the document's ``design.validated`` says whether
    the result is still the closed-loop stage's design.

    Raises
    ------
    PneumafitInputError
        Bad option values or an unreadable closed_loop.json.
    """
    from pneumafit.analysis.closed_loop import PLACEMENTS, largest_w0
    from pneumafit.models.layout import P
    from pneumafit.parameters_io import read_parameter_details, read_valve_law

    if order not in (4, 6):
        raise PneumafitInputError(f"option --order: expected 4 or 6, found {order}")
    if placement is not None and placement not in PLACEMENTS:
        raise PneumafitInputError(
            f"option --placement: expected one of {', '.join(PLACEMENTS)}, found {placement!r}"
        )
    if w0 is not None and not w0 > 0:
        raise PneumafitInputError(f"option --w0: expected a positive frequency, found {w0}")
    model, details = read_parameter_details(fit)
    valve = read_valve_law(fit)
    vec = parameter_vector({k: v["value"] for k, v in details.items()})
    stroke = float(vec[P["stroke"]])
    nominal = details["lambda"]["value"] if model == "constant-lambda" and "lambda" in details \
        else 15.0  # fmt: skip
    ran: dict = {}
    if closed_loop is not None:
        try:
            ran = json.loads(Path(closed_loop).read_text(encoding="utf-8"))["inputs"]
            ran_w0 = float(ran["w0_rad_s"])
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise PneumafitInputError(
                f"{closed_loop}: expected a closed_loop.json with inputs.w0_rad_s, found {exc}"
            ) from None
    defaults = {"placement": ran.get("placement", "dominant"),
                "compensate": ran.get("compensate", True),
                "lambda_e": ran.get("lambda_e", nominal), "umax": ran.get("umax_V", 10.0),
                "position": ran.get("position_m", 0.5 * stroke)}  # fmt: skip
    placement = defaults["placement"] if placement is None else placement
    compensate = defaults["compensate"] if compensate is None else compensate
    umax = defaults["umax"] if umax is None else umax
    lam = lambda_e if lambda_e is not None else defaults["lambda_e"]
    y_mid = position if position is not None else defaults["position"]
    grid = np.linspace(0.02, 0.98, 25) * stroke if positions is None else positions
    if w0 is None and ran:
        w0, rule = ran_w0, f"the closed-loop run's ({closed_loop})"
    elif w0 is None:
        w0 = largest_w0(vec, y_mid, step, umax=umax, lambda_e=lam, compensate=compensate,
                        placement=placement, valve=valve)  # fmt: skip
        rule = (
            f"largest_w0: the largest w0 whose order-4 and order-6 designs keep a "
            f"{step * 1e3:g} mm step within 90 % of {umax:g} V, as pneumafit closed-loop"
        )
    else:
        rule = "given (--w0)"
    reference_w0 = ran_w0 if ran else (w0 if rule.startswith("largest_w0") else None)
    validated = (
        reference_w0 is not None and w0 == reference_w0 and placement == defaults["placement"]
        and compensate == defaults["compensate"] and lam == defaults["lambda_e"]
        and umax == defaults["umax"] and y_mid == defaults["position"]
    )  # fmt: skip
    return build_export(
        details, model=model, source=Path(fit).name, positions=np.asarray(grid, dtype=float),
        order=order, w0=float(w0), lambda_e=lam, valve=valve, placement=placement,
        compensate=compensate, umax=umax, operating_position=y_mid, w0_rule=rule,
        validated=validated,
    )  # fmt: skip


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


def _c_header(doc: dict, name: str = "controller.h") -> str:
    grid, design, ctrl = doc["grid"], doc["design"], doc["controller"]
    n, order = len(grid["positions"]), design["order"]
    guard = "PNEUMAFIT_" + re.sub(r"[^A-Za-z0-9]", "_", Path(name).name).upper()
    lines = [
        f"/* pneumafit controller export (format pneumafit-controller-export v{VERSION}).",
        f" * Source: {doc['source']['file']} ({doc['source']['model']} model).",
        f" * Design: {design['description']}.",
        f" * Law: {ctrl['law']}.",
        f" * Schedule: {ctrl['schedule']}.",
        f" * States: {', '.join(f'{s} [{u}]' for s, u in zip(doc['states'], doc['state_units'], strict=True))}.",  # noqa: E501
        " * All values SI. Generated file: do not edit. */",
        f"#ifndef {guard}",
        f"#define {guard}",
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
        f"#define PF_CTRL_UMAX ({_c_number(ctrl['umax'])}) /* V, command limit */",
        f"#define PF_CTRL_PERIOD ({_c_number(ctrl['period'])}) /* s, sampling period */",
        f"#define PF_CTRL_DEADBAND ({_c_number(ctrl['deadband_amplitude'])}) /* V, a */",
        f"#define PF_CTRL_W0 ({_c_number(design['w0'])}) /* rad/s, design frequency */",
        "",
    ]
    for pname, p in doc["parameters"].items():
        macro = "PF_" + re.sub(r"[^A-Za-z0-9]", "_", pname).upper()
        note = f"{p['unit'] or '-'}"
        if p["interval_90"] is not None:
            note += f", 90% interval [{p['interval_90'][0]:.6g}, {p['interval_90'][1]:.6g}]"
        lines.append(f"#define {macro} ({_c_number(p['value'])}) /* {note} */")
    lines += [
        "",
        "/* measured state, SI */",
        "typedef struct {",
        "    double y, v, p_N, p_P, T_N, T_P; /* m, m/s, Pa, Pa, K, K */",
        "} pf_state;",
        "",
        "/* valve commands (V); v: controller output before the compensation */",
        "typedef struct {",
        "    double u_P, u_N, v;",
        "    int saturated; /* 1 when |u| was clipped to PF_CTRL_UMAX */",
        "} pf_command;",
        "",
        "/* one sampling period of the law above (controller.c): no allocation, no state */",
        "void pf_controller_step(const pf_state *state, double y_ref, pf_command *command);",
        "",
    ]
    text = "\n".join(lines) + "\n"
    text += _c_array("pf_positions", np.array(grid["positions"]).reshape(n))
    for key in ("u_e", "v_e", "p_P_e", "p_N_e", "T_e", "deadband_width"):
        text += _c_array(f"pf_{key}", np.array(grid[key]).reshape(n))
    text += _c_array("pf_A", np.array(grid["A"]).reshape(n, order, order))
    text += _c_array("pf_B", np.array(grid["B"]).reshape(n, order))
    text += _c_array("pf_K", np.array(grid["K"]).reshape(n, order))
    text += f"\n#endif /* {guard} */\n"
    return text


C_SOURCE = """\
/* pneumafit controller (format pneumafit-controller-export v{version}): the
 * exported law, one call per sampling period (PF_CTRL_PERIOD s). C99, no
 * allocation, no static state. Generated file: do not edit.
 * Build: cc -std=c99 -O2 -c controller.c  (ISO C: no fused multiply-add, so the
 * results match pneumafit's Python law bit for bit). */
#include <math.h>
#include "{header}"

static double pf_lerp(const double *table, int i, int j, double f)
{{
    return table[i] + f * (table[j] - table[i]);
}}

void pf_controller_step(const pf_state *state, double y_ref, pf_command *command)
{{
    const double x[6] = {{state->y, state->v, state->p_N, state->p_P, state->T_N, state->T_P}};
    const double y = state->y;
    double x_e[6];
    double f = 0.0, v, u, width;
    int i = 0, j, s, saturated = 0;
#if PF_N_POSITIONS > 1
    if (y <= pf_positions[0]) {{
        i = 0;
        f = 0.0;
    }} else if (y >= pf_positions[PF_N_POSITIONS - 1]) {{
        i = PF_N_POSITIONS - 2;
        f = 1.0;
    }} else {{
        while (y >= pf_positions[i + 1])
            i++;
        f = (y - pf_positions[i]) / (pf_positions[i + 1] - pf_positions[i]);
    }}
    j = i + 1;
#else
    j = 0;
#endif
    x_e[0] = y_ref;
    x_e[1] = 0.0;
    x_e[2] = pf_lerp(pf_p_N_e, i, j, f);
    x_e[3] = pf_lerp(pf_p_P_e, i, j, f);
    x_e[4] = pf_lerp(pf_T_e, i, j, f);
    x_e[5] = x_e[4];
    v = pf_lerp(pf_v_e, i, j, f) - (pf_K[i][0] + f * (pf_K[j][0] - pf_K[i][0])) * (y - x_e[0]);
    for (s = 1; s < PF_N_STATES; s++)
        v -= (pf_K[i][s] + f * (pf_K[j][s] - pf_K[i][s])) * (x[s] - x_e[s]);
    u = v;
    width = pf_lerp(pf_deadband_width, i, j, f);
    if (PF_CTRL_DEADBAND > 0.0 && width > 0.0)
        u = v + PF_CTRL_DEADBAND * tanh(v / width);
    if (u > PF_CTRL_UMAX) {{
        u = PF_CTRL_UMAX;
        saturated = 1;
    }} else if (u < -PF_CTRL_UMAX) {{
        u = -PF_CTRL_UMAX;
        saturated = 1;
    }}
    command->u_P = u;
    command->u_N = -u;
    command->v = v;
    command->saturated = saturated;
}}
"""


def c_source_path(header: str | os.PathLike[str]) -> Path:
    """The controller source written beside a header: ``controller.h`` -> ``controller.c``."""
    return Path(header).with_suffix(".c")


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


def mat_variables(doc: dict) -> dict[str, object]:
    """Top-level MATLAB variables of the .mat file (version-2 documents).

    ``A`` (order, order, n) and ``B`` (order, 1, n) as MATLAB's model arrays
    and ``ss(A, B, C, D)`` expect, ``C`` (order, order), ``D`` (order, 1),
    ``breakpoints`` (n, 1) positions (m), ``K`` (n, order), the equilibria
    and widths (n, 1), the constants ``umax``, ``Ts``, ``deadband_amplitude``,
    ``w0``, ``order``, the state names, and the whole document as the struct
    ``pneumafit``.
    """
    grid, ctrl, design = doc["grid"], doc["controller"], doc["design"]
    column = {k: np.asarray(grid[k], dtype=float).reshape(-1, 1)
              for k in ("u_e", "v_e", "p_P_e", "p_N_e", "T_e", "deadband_width")}  # fmt: skip
    a = np.asarray(grid["A"], dtype=float)
    b = np.asarray(grid["B"], dtype=float)
    return {
        "A": np.moveaxis(a, 0, 2),
        "B": np.moveaxis(b[:, :, None], 0, 2),
        "C": np.asarray(doc["linear_model"]["C"], dtype=float),
        "D": np.asarray(doc["linear_model"]["D"], dtype=float),
        "K": np.asarray(grid["K"], dtype=float),
        "breakpoints": np.asarray(grid["positions"], dtype=float).reshape(-1, 1),
        **column,
        "umax": float(ctrl["umax"]),
        "Ts": float(ctrl["period"]),
        "deadband_amplitude": float(ctrl["deadband_amplitude"]),
        "w0": float(design["w0"]),
        "order": int(design["order"]),
        "states": np.array(doc["states"], dtype=object),
        "pneumafit": _mat_safe(doc),
    }


def _csv(doc: dict) -> str:
    """The gain schedule, one row per breakpoint, '#' comment lines first."""
    grid, design, ctrl = doc["grid"], doc["design"], doc["controller"]
    units = {"V/m": "V_per_m", "V s/m": "V_s_per_m", "V/Pa": "V_per_Pa", "V/K": "V_per_K"}
    gains = [f"K_{s}_{units[u]}" for s, u in zip(doc["states"], ctrl["gain_units"], strict=True)]
    buffer = io.StringIO()
    for line in (
        f"pneumafit controller export v{VERSION}: {design['description']}",
        f"law: {ctrl['law']}",
        f"schedule: {ctrl['schedule']}",
        f"a = deadband_amplitude = {ctrl['deadband_amplitude']!r} V; umax = {ctrl['umax']!r} V; "
        f"period = {ctrl['period']!r} s",
    ):
        buffer.write(f"# {line}\n")
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["position_m", *gains, "v_e_V", "u_e_V", "p_N_e_Pa", "p_P_e_Pa", "T_e_K",
                     "deadband_width_V"])  # fmt: skip
    for i, y in enumerate(grid["positions"]):
        row = [y, *grid["K"][i]] + [grid[k][i] for k in ("v_e", "u_e", "p_N_e", "p_P_e", "T_e",
                                                         "deadband_width")]  # fmt: skip
        writer.writerow([repr(float(v)) for v in row])
    return buffer.getvalue()


def write_export(doc: dict, path: str | os.PathLike[str], fmt: str) -> Path:
    """Write the export in ``fmt`` (json, yaml, c, mat, csv), atomically.

    ``c`` writes the header at ``path`` (``.h``) and the controller source
    beside it (:func:`c_source_path`). Returns ``path``.
    """
    target = Path(path)
    if fmt not in FORMATS:
        raise PneumafitInputError(
            f"export: format: expected one of {', '.join(FORMATS)}, found {fmt!r}"
        )
    if fmt in ("c", "mat", "csv") and doc.get("version") != VERSION:
        raise PneumafitInputError(
            f"export: format {fmt}: expected a version-{VERSION} document, found "
            f"version {doc.get('version')}"
        )
    if fmt == "json":
        write_text_atomic(target, json.dumps(doc, indent=2) + "\n")
    elif fmt == "yaml":
        import yaml

        write_text_atomic(target, yaml.safe_dump(doc, sort_keys=False))
    elif fmt == "c":
        if target.suffix == ".c":
            raise PneumafitInputError(
                f"export: --out {target}: --format c writes a header and the controller source "
                f"beside it; expected the header's name (e.g. {target.with_suffix('.h').name})"
            )
        write_text_atomic(target, _c_header(doc, target.name))
        write_text_atomic(c_source_path(target),
                          C_SOURCE.format(version=VERSION, header=target.name))  # fmt: skip
    elif fmt == "csv":
        write_text_atomic(target, _csv(doc))
    else:
        from scipy.io import savemat

        with atomic_path(target) as tmp:
            with open(tmp, "wb") as stream:
                savemat(stream, mat_variables(doc), long_field_names=True)
    return target


def read_export(path: str | os.PathLike[str]) -> dict:
    """Read a JSON or YAML export back (exact round trip); versions 1 and 2.

    Raises
    ------
    PneumafitInputError
        A file that is not a controller export, or of a newer version.
    """
    file = Path(path)
    text = file.read_text(encoding="utf-8")
    if str(path).endswith((".yaml", ".yml")):
        import yaml

        try:
            doc = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise PneumafitInputError(f"{file}: expected a YAML document, found: {exc}") from None
    else:
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as exc:
            raise PneumafitInputError(f"{file}: expected a JSON document, found: {exc}") from None
    found = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
    if found != "pneumafit-controller-export":
        raise PneumafitInputError(
            f"{file}: format: expected 'pneumafit-controller-export', found {found!r}"
        )
    if doc.get("version") not in READABLE_VERSIONS:
        raise PneumafitInputError(
            f"{file}: version: expected one of {READABLE_VERSIONS}, found {doc.get('version')!r}"
        )
    return doc


__all__ = ["FORMATS", "VERSION", "build_export", "c_source_path", "export_document",
           "mat_variables", "read_export", "with_operating_position", "write_export"]  # fmt: skip
