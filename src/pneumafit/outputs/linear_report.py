"""JSON and figures of the linear analysis (paper Figs. 3-7).

Figures use matplotlib's Agg backend (no display needed); every file is
written atomically.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from pneumafit.analysis import gain_schedule, itae_poles, linearize
from pneumafit.fileio import atomic_path, write_text_atomic


def _complex_list(values: np.ndarray) -> list[list[float]]:
    return [[float(v.real), float(v.imag)] for v in np.asarray(values).ravel()]


def _save(fig, path: Path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120, bbox_inches="tight")


def write_linear(
    parameters: np.ndarray,
    positions: np.ndarray,
    out: Path,
    *,
    lambda_e: float,
    valve: str = "iso6358",
) -> dict:
    """Equilibria, (A, B) and open-loop poles of both models over positions.

    ``valve`` is the valve law of the parameters (a fit's ``structure.valve``).

    Writes ``out/linear.json`` and ``out/open_loop_poles.png`` (Figs. 3-5).
    Positions without an equilibrium are listed with the reason.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    entries = []
    poles = {4: [], 6: []}
    for y in positions:
        entry: dict = {"y": float(y)}
        for order in (4, 6):
            try:
                lin = linearize(parameters, float(y), order=order, lambda_e=lambda_e,
                                valve=valve)  # fmt: skip
            except ValueError as exc:
                entry["error"] = str(exc)
                break
            eq = lin.equilibrium
            entry["equilibrium"] = {"p_P": eq.p_P, "p_N": eq.p_N, "T": eq.T, "u": eq.u}
            entry[f"order_{order}"] = {
                "states": list(lin.states),
                "A": lin.A.tolist(),
                "B": lin.B.ravel().tolist(),
                "poles": _complex_list(lin.poles),
            }
            poles[order].append((float(y), lin.poles))
        entries.append(entry)
    doc = {
        "format": "pneumafit-linear",
        "version": 1,
        "lambda_e": lambda_e,
        "valve": valve,
        "units": {"A": "SI, states [y m, v m/s, p_N Pa, p_P Pa, T_N K, T_P K]", "B": "per V"},
        "positions": entries,
    }
    write_text_atomic(out / "linear.json", json.dumps(doc, indent=2) + "\n")

    fig, axes = plt.subplots(1, 3, figsize=(16, 4.5), layout="constrained")
    for ax, order in zip(axes[:2], (4, 6), strict=True):
        ys = [y for y, _ in poles[order]]
        for y, pl in poles[order]:
            sc = ax.scatter(pl.real, pl.imag, c=[y] * pl.size, cmap="viridis", s=18,
                            vmin=min(ys), vmax=max(ys))  # fmt: skip
        ax.set_title(f"open-loop poles, {order}th-order model (Fig. {3 if order == 4 else 4})")
        ax.set_xlabel("real part (1/s)")
        ax.set_ylabel("imaginary part (1/s)")
        ax.grid(True, alpha=0.3)
        fig.colorbar(sc, ax=ax, label="piston position (m)")
    mid = min(poles[4], key=lambda e: abs(e[0] - np.median([y for y, _ in poles[4]])))
    mid6 = min(poles[6], key=lambda e: abs(e[0] - mid[0]))
    axes[2].scatter(mid[1].real, mid[1].imag, marker="x", s=60, label="polytropic (4)")
    axes[2].scatter(mid6[1].real, mid6[1].imag, marker="o", facecolors="none", edgecolors="C3",
                    s=60, label=f"heat, lambda_e = {lambda_e:g} (6)")  # fmt: skip
    axes[2].set_title(f"both models at y = {mid[0]:.3f} m (Fig. 5)")
    axes[2].set_xlabel("real part (1/s)")
    axes[2].grid(True, alpha=0.3)
    axes[2].legend()
    _save(fig, out / "open_loop_poles.png")
    plt.close(fig)
    return doc


def write_design(
    parameters: np.ndarray,
    positions: np.ndarray,
    out: Path,
    *,
    order: int,
    w0: float,
    lambda_e: float,
    valve: str = "iso6358",
) -> dict:
    """Gain schedule K(y) placing the ITAE poles, and the closed-loop poles.

    ``valve`` is the valve law of the parameters.

    Writes ``out/design_<order>.json``, ``out/gain_schedule_<order>.png`` and
    ``out/closed_loop_poles_<order>.png`` (Figs. 6-7).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    sched = gain_schedule(parameters, positions, order=order, w0=w0, lambda_e=lambda_e,
                          valve=valve)  # fmt: skip
    states = ["y", "v", "p_N", "p_P", "T_N", "T_P"][:order]
    units = ["V/m", "V s/m", "V/Pa", "V/Pa", "V/K", "V/K"][:order]
    doc = {
        "format": "pneumafit-design",
        "version": 1,
        "order": order,
        "w0": w0,
        "lambda_e": lambda_e if order == 6 else None,
        "valve": valve,
        "law": "delta u = -K (x - x_e), u = u_e + delta u",
        "target_poles": _complex_list(itae_poles(order, w0)),
        "states": states,
        "gain_units": units,
        "schedule": [
            {
                "y": float(y),
                "K": None if not np.all(np.isfinite(k)) else k.tolist(),
                "closed_loop_poles": _complex_list(cl) if np.all(np.isfinite(k)) else None,
            }
            for y, k, cl in zip(sched["positions"], sched["K"], sched["closed_loop"], strict=True)
        ],
    }
    write_text_atomic(out / f"design_{order}.json", json.dumps(doc, indent=2) + "\n")

    fig, axes = plt.subplots(1, order, figsize=(3.2 * order, 3.2))
    for i, ax in enumerate(axes):
        ax.plot(sched["positions"], sched["K"][:, i], "o-", ms=3)
        ax.set_title(f"K[{states[i]}] ({units[i]})", fontsize=9)
        ax.set_xlabel("y (m)")
        ax.grid(True, alpha=0.3)
    fig.suptitle(f"gain schedule, order {order}, w0 = {w0:g} rad/s")
    fig.tight_layout()
    _save(fig, out / f"gain_schedule_{order}.png")
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6, 4.5))
    ok = np.all(np.isfinite(sched["K"]), axis=1)
    for y, cl in zip(sched["positions"][ok], sched["closed_loop"][ok], strict=True):
        sc = ax.scatter(cl.real, cl.imag, c=[y] * cl.size, cmap="viridis", s=18,
                        vmin=sched["positions"].min(), vmax=sched["positions"].max())  # fmt: skip
    target = itae_poles(order, w0)
    ax.scatter(target.real, target.imag, marker="+", s=120, c="k", label="ITAE target")
    ax.set_title(f"closed-loop poles, order {order} (Fig. {6 if order == 4 else 7})")
    ax.set_xlabel("real part (1/s)")
    ax.set_ylabel("imaginary part (1/s)")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.colorbar(sc, ax=ax, label="piston position (m)")
    _save(fig, out / f"closed_loop_poles_{order}.png")
    plt.close(fig)
    return doc
