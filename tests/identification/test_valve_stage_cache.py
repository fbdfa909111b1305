"""The valve stage is shared by the fits of one campaign (same flow tests,
valve law, seed and options), and sharing it changes no number.

Campaign: the virtual rig's flow tests of both valves plus one charge test
(the kernel's own laws; what is tested is the bookkeeping of the cache, not
a recovery, so the inverse crime does not matter here).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from pneumafit.campaign import read_campaign
from pneumafit.identification import FitOptions, identify, staged
from pneumafit.virtual_rig import BlockedTest, FlowTest, Protocol, VirtualRig

BAR = 1.0e5


@pytest.fixture(scope="module")
def flows_campaign(tmp_path_factory: pytest.TempPathFactory) -> object:
    cmds = (-10.0, -3.0, -0.4, 0.0, 0.4, 3.0, 10.0)
    tests = (
        FlowTest(file="flow_P.h5", chamber="P", commands=cmds, pressures=(3 * BAR, 5 * BAR),
                 dwell=0.3),
        FlowTest(file="flow_N.h5", chamber="N", commands=cmds, pressures=(3 * BAR, 5 * BAR),
                 dwell=0.3),
        BlockedTest(file="charge_P.h5", kind="charge", chamber="P", position=0.1,
                    amplitude=10.0, opening_time=0.3, duration=1.5),
    )  # fmt: skip
    folder: Path = tmp_path_factory.mktemp("valve_cache") / "camp"
    VirtualRig(seed=4).write(folder, Protocol(name="flows", description="flows", tests=tests))
    return read_campaign(folder)


def _valve_values(result: staged.FitResult) -> dict[str, float]:
    est = result.stage("valve").estimate
    assert est is not None
    return {n: est.parameters[n].value for n in est.parameters.free_names}


def test_second_fit_reuses_the_valve_stage_and_gets_the_same_numbers(
    flows_campaign: object,
) -> None:
    opts = FitOptions(mcmc=False)
    staged._VALVE_STAGES.clear()
    first = identify(flows_campaign, "polytropic", options=opts, seed=2)  # type: ignore[arg-type]
    lines: list[str] = []
    shared = identify(flows_campaign, "constant-lambda", options=opts, seed=2, log=lines.append)  # type: ignore[arg-type]
    assert any("valve: the stage of an earlier fit of this campaign reused" in x for x in lines)
    assert _valve_values(shared) == _valve_values(first)
    # the same fit without the cache: every number identical
    staged._VALVE_STAGES.clear()
    alone = identify(flows_campaign, "constant-lambda", options=opts, seed=2)  # type: ignore[arg-type]
    assert _valve_values(alone) == _valve_values(shared)
    assert alone.parameters.values() == shared.parameters.values()
    # another seed or another valve law is another stage
    lines.clear()
    identify(flows_campaign, "constant-lambda", options=opts, seed=3, log=lines.append)  # type: ignore[arg-type]
    assert not any("reused" in x for x in lines)
