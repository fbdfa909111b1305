"""The exported C controller compiled and run in the loop (software in the loop).

:func:`compile_controller` builds ``controller.c`` (written by
:func:`pneumafit.outputs.export.write_export` with ``fmt="c"``) into a shared
library with the system's C compiler; :class:`CController` calls its
``pf_controller_step`` through ctypes with the same signature as the Python
law (``controller(state, y_ref) -> u_P``), so either drives
:func:`pneumafit.simulation.sampled.simulate_sampled`. :func:`software_in_the_loop`
runs the closed-loop stage's step test twice on the nonlinear model, once
with the Python law of the export (:class:`pneumafit.analysis.controller.ScheduledController`)
and once with the compiled C code, and compares the commands and the figures.
"""

from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from pneumafit.errors import PneumafitComputationError

#: Flags of the build: ISO C99 (which also turns off fused multiply-add
#: contraction in GCC, so the arithmetic is the Python law's), warnings as errors.
C_FLAGS = ("-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-fPIC", "-shared")


def find_compiler() -> str | None:
    """The C compiler to use: ``$CC``, else ``cc``, ``gcc`` or ``clang`` on the PATH."""
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return shutil.which(name)
    return None


def compile_controller(source: str | os.PathLike[str], library: str | os.PathLike[str],
                       *, compiler: str | None = None) -> Path:  # fmt: skip
    """Compile the exported ``controller.c`` into a shared library.

    Raises
    ------
    PneumafitComputationError
        No C compiler, or the compilation failed (its messages included).
    """
    cc = compiler or find_compiler()
    if cc is None:
        raise PneumafitComputationError("no C compiler found (set CC, or install cc/gcc/clang)")
    src, lib = Path(source).resolve(), Path(library).resolve()
    cmd = [cc, *C_FLAGS, "-o", str(lib), str(src), "-lm"]
    res = subprocess.run(cmd, capture_output=True, text=True, cwd=src.parent)
    if res.returncode != 0:
        raise PneumafitComputationError(f"compiling {src} failed ({' '.join(cmd)}):\n{res.stderr}")
    return lib


class _State(ctypes.Structure):
    _fields_ = [(name, ctypes.c_double) for name in ("y", "v", "p_N", "p_P", "T_N", "T_P")]


class _Command(ctypes.Structure):
    _fields_ = [("u_P", ctypes.c_double), ("u_N", ctypes.c_double), ("v", ctypes.c_double),
                ("saturated", ctypes.c_int)]  # fmt: skip


class CController:
    """The compiled ``pf_controller_step`` as ``controller(state, y_ref) -> u_P`` (V).

    Parameters
    ----------
    library : path
        Shared library from :func:`compile_controller`.
    """

    def __init__(self, library: str | os.PathLike[str]) -> None:
        self._lib = ctypes.CDLL(str(Path(library).resolve()))
        self._step = self._lib.pf_controller_step
        self._step.argtypes = [ctypes.POINTER(_State), ctypes.c_double,
                               ctypes.POINTER(_Command)]  # fmt: skip
        self._step.restype = None
        self._state = _State()
        self._command = _Command()

    def command(self, state: Sequence[float], y_ref: float) -> tuple[float, float, bool]:
        """(u_P, v, saturated), as :meth:`ScheduledController.command`."""
        s = self._state
        s.y, s.v, s.p_N, s.p_P, s.T_N, s.T_P = (float(v) for v in state[:6])
        self._step(ctypes.byref(s), float(y_ref), ctypes.byref(self._command))
        return self._command.u_P, self._command.v, bool(self._command.saturated)

    def __call__(self, state: Sequence[float], y_ref: float) -> float:
        return self.command(state, y_ref)[0]


def software_in_the_loop(
    document: Mapping,
    header: str | os.PathLike[str],
    plant_parameters: Mapping[str, float] | np.ndarray,
    *,
    plant="convection",
    y_mid: float,
    steps: Sequence[float] = (0.03, 0.0, -0.03, 0.0),
    hold: float = 2.5,
    compiler: str | None = None,
) -> dict:
    """Run the exported controller in Python and as compiled C on the nonlinear plant.

    Parameters
    ----------
    document : mapping
        The export document (version 2) the header was written from.
    header : path
        The written ``controller.h``; ``controller.c`` beside it is compiled
        (into a temporary folder).
    plant_parameters, plant
        The nonlinear plant (parameters, structure).
    y_mid, steps, hold
        The step test (:func:`pneumafit.analysis.closed_loop.step_reference`),
        started at the equilibrium of the breakpoint nearest ``y_mid``.

    Returns
    -------
    dict
        ``python`` and ``c``: the figures of each run
        (:func:`pneumafit.analysis.controller.metrics_document`);
        ``max_command_difference_V``: the largest |u_P(C) - u_P(Python)| over
        the samples; ``identical_figures``: every figure equal; ``compiler``,
        ``flags``, ``samples``.

    Raises
    ------
    PneumafitComputationError
        No C compiler, or the code does not compile.
    """
    from pneumafit.analysis.controller import ScheduledController, metrics_document, run_sampled
    from pneumafit.outputs.export import c_source_path

    law = ScheduledController.from_export(document)
    grid = document["grid"]
    k = int(np.argmin(np.abs(np.asarray(grid["positions"]) - y_mid)))
    initial = {"y": y_mid, "p_P": grid["p_P_e"][k], "p_N": grid["p_N_e"][k],
               "T_P": grid["T_e"][k], "T_N": grid["T_e"][k]}  # fmt: skip
    cc = compiler or find_compiler()
    if cc is None:
        raise PneumafitComputationError("no C compiler found (set CC, or install cc/gcc/clang)")
    kwargs = dict(y_mid=y_mid, steps=steps, hold=hold, plant=plant, initial=initial,
                  umax=law.umax, period=law.period)  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="pneumafit-sil-") as tmp:
        lib = compile_controller(c_source_path(header), Path(tmp) / "libpf_controller.so",
                                 compiler=cc)  # fmt: skip
        c_run = run_sampled(CController(lib), plant_parameters, **kwargs)
    py_run = run_sampled(law, plant_parameters, **kwargs)
    diff = np.abs(c_run.channels["u_P"] - py_run.channels["u_P"])
    py_doc, c_doc = metrics_document(py_run), metrics_document(c_run)
    return {
        "python": py_doc,
        "c": c_doc,
        "max_command_difference_V": float(np.max(diff)) if np.all(np.isfinite(diff)) else None,
        "identical_figures": py_doc == c_doc,
        "compiler": cc,
        "flags": " ".join(C_FLAGS),
        "samples": int(py_run.time.size),
        "period_s": law.period,
        "position_m": y_mid,
        "steps_m": [float(s) for s in steps],
        "hold_s": hold,
    }


def sil_from_closed_loop(
    document: Mapping, header: str | os.PathLike[str], closed_loop: str | os.PathLike[str]
) -> dict:
    """:func:`software_in_the_loop` on the plant and step test of a closed-loop run.

    ``closed_loop`` is the run's ``closed_loop.json``: its inputs name the
    plant file (a plant whose heat law is not convection runs as the
    convection model with its values, as the closed-loop stage does), the
    position, the steps and the hold. Returns the SIL document (format
    ``pneumafit-sil`` version 1) with those inputs.
    """
    import dataclasses
    import json

    from pneumafit.analysis.closed_loop import read_plant_file
    from pneumafit.models import parameter_vector
    from pneumafit.models.structure import get_structure

    inputs = json.loads(Path(closed_loop).read_text(encoding="utf-8"))["inputs"]
    structure, values = read_plant_file(inputs["plant"])
    if structure.heat != "convection":
        structure = dataclasses.replace(get_structure("convection"), valve=structure.valve)
    result = software_in_the_loop(
        document, header, parameter_vector(values), plant=structure,
        y_mid=float(inputs["position_m"]), steps=[float(s) for s in inputs["steps_m"]],
        hold=float(inputs["hold_s"]),
    )  # fmt: skip
    return {"format": "pneumafit-sil", "version": 1, "run": True,
            "plant": str(inputs["plant"]), "design": document["design"]["description"],
            **result}  # fmt: skip


def sil_for_fit(
    document: Mapping,
    header: str | os.PathLike[str],
    fit: str | os.PathLike[str],
    *,
    closed_loop: str | os.PathLike[str] | None = None,
    steps: Sequence[float] = (0.03, 0.0, -0.03, 0.0),
    hold: float = 2.5,
) -> dict:
    """Software in the loop for ``pneumafit export --sil``.

    With ``closed_loop`` (a ``closed_loop.json``), that run's plant and steps
    (:func:`sil_from_closed_loop`); otherwise the fit itself as the plant (as
    ``pneumafit closed-loop`` without ``--plant``) and the closed-loop
    stage's default steps from the export's design position.
    """
    import dataclasses

    from pneumafit.analysis.closed_loop import read_plant_file
    from pneumafit.models import parameter_vector
    from pneumafit.models.structure import get_structure

    if closed_loop is not None:
        return sil_from_closed_loop(document, header, closed_loop)
    structure, values = read_plant_file(fit)
    if structure.heat != "convection":
        structure = dataclasses.replace(get_structure("convection"), valve=structure.valve)
    result = software_in_the_loop(
        document, header, parameter_vector(values), plant=structure,
        y_mid=float(document["design"]["operating_position"]), steps=steps, hold=hold,
    )  # fmt: skip
    return {"format": "pneumafit-sil", "version": 1, "run": True, "plant": str(fit),
            "design": document["design"]["description"], **result}  # fmt: skip
