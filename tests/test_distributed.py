"""Dask distributed: many campaigns and the MCMC's log posterior give the serial numbers."""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import emcee
import numpy as np
import pytest
from rich.console import Console
from scipy import stats

from pneumafit.campaign import read_campaign
from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.distributed import (
    DaskPool,
    dask_client,
    distributed_log_prob,
    fit_many,
    fit_many_command,
)
from pneumafit.identification import (
    LogLikelihood,
    LogPosterior,
    ParameterSet,
    Problem,
    fit_structure,
    run_mcmc,
)
from pneumafit.virtual_rig import VirtualRig
from pneumafit.virtual_rig.protocol import quick_protocol

pytest.importorskip("distributed")

#: Campaign seeds: two rigs of a small fleet.
SEEDS = (1, 2)
#: A port nothing listens on: connecting is refused at once.
NOWHERE = "tcp://127.0.0.1:1"
VALVE = ("valve_C_supply", "valve_b_supply", "valve_m", "valve_overlap")


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    base = tmp_path_factory.mktemp("fleet")
    folders = []
    for s in SEEDS:
        folder = base / f"rig{s}"
        VirtualRig(seed=s).write(folder, quick_protocol())
        folders.append(folder)
    return folders


@pytest.fixture(scope="module")
def client() -> Iterator[object]:
    """A LocalCluster of two single-threaded worker processes."""
    with dask_client(None, 2) as c:
        yield c


def _fit(path: Path) -> dict:
    doc = json.loads(path.read_text())
    return {k: doc[k] for k in ("parameters", "nuisance", "correlation", "metrics", "noise")}


def test_fit_many_on_a_local_cluster_equals_the_serial_run(
    campaigns: list[Path], client: object, tmp_path: Path
) -> None:
    serial = fit_many(campaigns, "convection", tmp_path / "serial", seed=3, mcmc=False)
    # the command's path: an existing scheduler by address, one task per campaign
    console = Console(file=io.StringIO(), width=200)
    code = fit_many_command(
        campaigns, "convection", tmp_path / "dask", scheduler=client.scheduler.address,
        workers=None, seed=3, mcmc=False, walkers=None, steps=None, console=console,
    )  # fmt: skip
    log = console.file.getvalue()
    assert code == 0, log
    assert "[2/2]" in log and "2 of 2 fits written" in log
    for c in campaigns:
        assert serial[c].code == 0, serial[c].log
        # same code, same seed, same inputs: the documents agree exactly
        # (bar the provenance: time stamps and the output folder)
        assert _fit(serial[c].fit) == _fit(tmp_path / "dask" / c.name / "fit.json")
    values = [_fit(serial[c].fit)["parameters"]["xi"]["value"] for c in campaigns]
    assert values[0] != values[1]  # two different rigs, not one fit twice


def _valve_posterior(folder: Path) -> tuple[LogPosterior, ParameterSet]:
    """The valve stage's posterior on one flow test: cheap (about 1 ms a set)."""
    camp = read_campaign(folder)
    structure = fit_structure("convection")
    recs = [r for r in camp.by_role("fit") if r.kind == "flow"]
    values = dict(camp.rig.as_parameters())
    prob = Problem(recs, structure, values, channels=("qm_P",), initial_nuisance=False)
    ps = ParameterSet.for_model(structure, camp.rig.as_parameters()).only_free(VALVE)
    return LogPosterior(LogLikelihood(prob, ps)), ps


def test_distributed_log_posterior_gives_the_serial_chain(
    campaigns: list[Path], client: object
) -> None:
    post, ps = _valve_posterior(campaigns[0])
    remote = distributed_log_prob(post, client, chunks=3)
    z = ps.to_internal() + 1e-3 * np.random.default_rng(0).standard_normal((7, ps.n_free))
    assert np.array_equal(remote(z), post(z))  # pickled to the workers, chunked, in order
    kw = {"n_walkers": 8, "n_steps": 20, "seed": 5}
    serial = run_mcmc(post, ps, ps.to_internal(), **kw)
    dist = run_mcmc(remote, ps, ps.to_internal(), **kw)
    remote.close()
    assert np.isfinite(serial.log_prob).all()
    assert np.array_equal(dist.chain, serial.chain)
    # the same chain; a log-probability computed in a worker process may differ
    # from the calling process's in its last bits (measured 2.8e-14 on values
    # ~100, once in 160: 1e-16 relative), never enough to change an acceptance
    np.testing.assert_allclose(dist.log_prob, serial.log_prob, rtol=1e-13, atol=0.0)


def test_dask_pool_is_an_emcee_pool(client: object) -> None:
    target = stats.multivariate_normal(mean=[1.0, -2.0], cov=[[1.0, 0.9], [0.9, 4.0]])
    assert DaskPool(client).map(abs, [-1, 2, -3]) == [1, 2, 3]
    start = np.random.default_rng(1).standard_normal((6, 2))
    chains = []
    for pool in (None, DaskPool(client)):
        sampler = emcee.EnsembleSampler(6, 2, target.logpdf, pool=pool)
        sampler.random_state = np.random.RandomState(7).get_state()
        sampler.run_mcmc(start, 10)
        chains.append(sampler.get_chain())
    assert np.array_equal(chains[0], chains[1])


def test_unreachable_scheduler_is_named_in_the_error() -> None:
    with pytest.raises(PneumafitInputError, match=r"--scheduler 'tcp://127\.0\.0\.1:1'"):
        with dask_client(NOWHERE, timeout=2):
            pass


def test_bad_input_is_reported_before_any_cluster_starts(
    campaigns: list[Path], tmp_path: Path
) -> None:
    console = Console(file=io.StringIO(), width=200)
    twice = [campaigns[0], campaigns[0]]
    code = fit_many_command(
        twice, "adiabatic", tmp_path / "fits", scheduler=NOWHERE, workers=None, seed=0,
        mcmc=False, walkers=None, steps=None, console=console,
    )  # fmt: skip
    log = console.file.getvalue()
    assert code == 2
    assert "same folder name 'rig1'" in log and "option --model: expected one of" in log
    assert "scheduler" not in log and not (tmp_path / "fits").exists()


def test_cli_unreachable_scheduler_exits_2_without_traceback(
    campaigns: list[Path], tmp_path: Path
) -> None:
    env = dict(os.environ, DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT="2s")
    res = subprocess.run(
        [sys.executable, "-m", "pneumafit", "fit-many", *map(str, campaigns), "--out",
         str(tmp_path / "fits"), "--scheduler", NOWHERE, "--no-mcmc"],
        capture_output=True, text=True, env=env, timeout=300,
    )  # fmt: skip
    assert res.returncode == 2, res.stdout + res.stderr
    assert "127.0.0.1:1" in res.stdout and "cannot reach a Dask scheduler" in res.stdout
    assert "Traceback" not in res.stdout + res.stderr
    assert not (tmp_path / "fits").exists()


def test_without_dask_the_error_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    """Plumbing: Dask is an optional extra; its absence is bad input, not a traceback."""
    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails as if not installed
    with pytest.raises(PneumafitInputError, match=r"pip install 'pneumafit\[distributed\]'"):
        with dask_client(None, 1):
            pass


def test_workers_run_one_numba_thread(client: object) -> None:
    """Each worker's numba uses one thread (else workers x cores threads run at once)."""

    def threads() -> tuple[str | None, int]:
        import numba

        from pneumafit.distributed import _single_threaded

        _single_threaded()
        return os.environ.get("NUMBA_NUM_THREADS"), numba.get_num_threads()

    env, n = client.submit(threads, pure=False).result()  # type: ignore[attr-defined]
    assert (env, n) == ("1", 1)


def test_fit_many_passes_the_valve_and_friction_laws_to_each_fit(
    campaigns: list[Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Plumbing: ``--valve`` and ``--friction`` reach every campaign's
    ``pneumafit fit`` (a stub records them), and a name no registered law
    has is refused before any cluster starts, with the hint to --parts."""
    import pneumafit.cli.fit as cli_fit

    seen: list[tuple[str, str]] = []

    def stub(*args: object, valve: str = "", friction: str = "", **kw: object) -> int:
        seen.append((valve, friction))
        return 2

    monkeypatch.setattr(cli_fit, "fit_command", stub)
    fit_many(campaigns, "convection", tmp_path / "fits", mcmc=False, valve="map",
             friction="lugre")  # fmt: skip
    assert seen == [("map", "lugre")] * len(campaigns)
    console = Console(file=io.StringIO(), width=200)
    code = fit_many_command(
        campaigns, "convection", tmp_path / "bad", scheduler=NOWHERE, workers=None, seed=0,
        mcmc=False, walkers=None, steps=None, console=console, valve="nope", friction="nope",
    )  # fmt: skip
    log = console.file.getvalue()
    assert code == 2 and "scheduler" not in log
    assert "option --valve: expected one of iso6358, map" in log and "--parts" in log
    assert "option --friction: expected one of auto, switch, lugre" in log
