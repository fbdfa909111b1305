"""The discovery result read in a notebook or a console: a short repr and a summary.

Plumbing only (no fit): a hand-made result whose two refits are one kept and
one rejected.
"""

from __future__ import annotations

from pneumafit.discovery.refit import Discovery, Model, Step
from pneumafit.models import ModelStructure


def _model(effects: tuple[str, ...], p_rmse: float) -> Model:
    rmse = {"fit": {"p_P": p_rmse, "p_N": p_rmse}, "validate": {"p_P": p_rmse, "p_N": p_rmse}}
    return Model(effects=effects, structure=ModelStructure("convection"), values={},
                 parameters=None, log_likelihood=-1.0, n_parameters=3, n_data=10,
                 rmse=rmse)  # fmt: skip


def test_discovery_repr_and_summary() -> None:
    base, final = _model((), 12869.0), _model(("external_leakage",), 3481.0)
    steps = [
        Step(1, "external_leakage", {}, final, True, "kept: BIC -54489"),
        Step(2, "supply_pressure_drop", {}, None, False, "a measured channel 10 % worse"),
    ]
    d = Discovery(base=base, final=final, selected=["external_leakage"], attributions=[],
                  steps=steps, noise=401.0, unexplained=True, statement="partly explained.",
                  seed=0, seconds=540.0)  # fmt: skip
    text = repr(d)
    assert len(text) < 200, text
    assert "external_leakage" in text and "12869 -> 3481 Pa" in text
    summary = d.summary()
    assert "round 1: external_leakage: kept" in summary
    assert "round 2: supply_pressure_drop: rejected (a measured channel 10 % worse)" in summary
    assert summary.endswith("partly explained.")
