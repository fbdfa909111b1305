"""Beyond one machine: many campaigns and the MCMC's log posterior on Dask distributed.

Two things are distributed (``docs/distributed.md``):

- campaigns: :func:`fit_many` runs one task per campaign, each calling
  :func:`~pneumafit.cli.fit.fit_command` into
  ``OUT/<campaign folder name>/`` on a worker (``pneumafit fit-many``);
- the log posterior of one MCMC: :class:`DistributedLogProb` splits each
  batch of walkers into chunks evaluated on the workers and is passed to
  :func:`~pneumafit.identification.sampling.run_mcmc` in place of the
  serial log posterior. :class:`DaskPool` is the same routing for code that
  wants a ``pool.map`` (emcee with ``vectorize=False``).

Neither changes a result: a campaign's fit runs the same code with the same
seed wherever it runs, and emcee draws its random numbers in the calling
process, so the chain depends only on the log-posterior values, which depend
only on each parameter set (the batched simulator evaluates the sets
independently). The tests check both against the serial run (log-probabilities from a worker
process may differ in their last bits, 1e-16 relative).

:func:`dask_client` connects to an existing scheduler by address, or starts
a :class:`distributed.LocalCluster` of single-threaded worker processes.
"""

from __future__ import annotations

import io
import os
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from rich.console import Console
from rich.text import Text

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.cli.console import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_OK,
    LogConsole,
    folder_problem,
    int_problem,
    report_problems,
)

if TYPE_CHECKING:
    from distributed import Client

__all__ = [
    "CampaignFit",
    "DaskPool",
    "DistributedLogProb",
    "dask_client",
    "distributed_log_prob",
    "fit_many",
    "fit_many_command",
]


#: What a user installs to run on Dask (pyproject's optional extra).
DASK_EXTRA = "pip install 'pneumafit[distributed]'"


def _require_dask() -> tuple[Any, Any]:
    """``distributed.Client`` and ``LocalCluster``, or a clear error naming the extra.

    Raises
    ------
    PneumafitInputError
        Dask distributed is not installed (it is an optional extra).
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:
        raise PneumafitInputError(
            f"running on Dask needs the optional extra: {DASK_EXTRA} "
            f"(expected the package 'distributed', found none: {exc})"
        ) from None
    return Client, LocalCluster


def _single_threaded() -> None:
    """One numba thread in this worker process, whatever its environment says.

    A remote worker was not started by :func:`dask_client` and may not have
    ``NUMBA_NUM_THREADS=1``: without this, each task's parallel kernels use
    every core of the worker's machine, once per worker. Outside a worker
    (``fit-many`` without a cluster) nothing changes.
    """
    try:
        from distributed import get_worker

        get_worker()
    except (ImportError, ValueError):  # not on a Dask worker
        return
    import numba

    if numba.get_num_threads() > 1:
        numba.set_num_threads(1)


@contextmanager
def dask_client(
    scheduler: str | None = None, n_workers: int | None = None, *, timeout: float | None = None
) -> Iterator[Client]:
    """A Dask client: an existing scheduler by address, or a local cluster.

    Parameters
    ----------
    scheduler : str, optional
        Address of a running scheduler (``tcp://host:8786``). None starts a
        :class:`distributed.LocalCluster` with ``threads_per_worker=1`` and
        worker processes (the simulator holds the GIL-free numba kernels,
        but a fit is one long Python loop per campaign: processes, not
        threads), closed on exit with the client.
    n_workers : int, optional
        Workers of the local cluster (default: one per core). Ignored with
        ``scheduler``.
    timeout : float, optional
        Seconds to wait for the scheduler (default: Dask's
        ``distributed.comm.timeouts.connect``, 30 s unless configured, e.g.
        by the environment variable ``DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT``).

    Yields
    ------
    distributed.Client

    Raises
    ------
    PneumafitInputError
        The scheduler cannot be reached (the message names the address), or
        ``n_workers`` is not a positive integer.
    """
    Client, LocalCluster = _require_dask()

    if n_workers is not None and (isinstance(n_workers, bool) or n_workers < 1):
        raise PneumafitInputError(
            f"option --workers: expected an integer >= 1, found {n_workers!r}"
        )
    if scheduler is not None:
        kwargs: dict[str, Any] = {} if timeout is None else {"timeout": timeout}
        try:
            client = Client(scheduler, **kwargs)
        except (OSError, TimeoutError, ValueError, TypeError) as exc:
            raise PneumafitInputError(
                f"option --scheduler {scheduler!r}: cannot reach a Dask scheduler at this "
                f"address ({type(exc).__name__}: {exc}); expected the address a running "
                "'dask scheduler' prints, e.g. tcp://10.0.0.5:8786, or no --scheduler for "
                "a local cluster"
            ) from None
        try:
            yield client
        finally:
            client.close()
        return
    # one numba thread per worker process (else each worker's parallel kernels
    # start one thread per core: workers x cores threads on the machine)
    cluster = LocalCluster(
        n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None,
        env={"NUMBA_NUM_THREADS": "1"},
    )  # fmt: skip
    try:
        client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
    finally:
        cluster.close()


# ------------------------------------------------------------------ campaigns


@dataclass(frozen=True)
class CampaignFit:
    """Outcome of one campaign's fit in :func:`fit_many`.

    Attributes
    ----------
    campaign : Path
        The campaign as given.
    code : int
        :func:`~pneumafit.cli.fit.fit_command`'s exit status
        (0 ok, 1 failed, 2 bad input, 130 interrupted).
    fit : Path or None
        ``OUT/<name>/fit.json`` when ``code`` is 0.
    error : str or None
        The last message of a failed fit (None when ``code`` is 0).
    log : str
        Everything the fit printed (on the worker).
    seconds : float
        Wall time of the fit where it ran.
    """

    campaign: Path
    code: int
    fit: Path | None
    error: str | None
    log: str
    seconds: float


def _campaign_name(campaign: Path) -> str:
    """Folder name of a campaign given as its folder or its campaign.toml."""
    path = Path(campaign)
    return path.parent.name if path.suffix == ".toml" else path.name


def _check_campaigns(campaigns: Sequence[Path], out: Path) -> list[Path]:
    """The campaigns as paths; raises when none, or when two share a folder name."""
    paths = [Path(c) for c in campaigns]
    if not paths:
        raise PneumafitInputError("fit-many: expected at least one campaign, found none")
    names: dict[str, Path] = {}
    for c in paths:
        name = _campaign_name(c)
        if name in names:
            raise PneumafitInputError(
                f"fit-many: campaigns {os.fspath(names[name])!r} and {os.fspath(c)!r} have the "
                f"same folder name {name!r}: expected distinct names (each names its folder "
                f"in {os.fspath(out)!r})"
            )
        names[name] = c
    return paths


def _fit_one(
    campaign: str,
    model: str,
    out: str,
    walkers: int | None,
    steps: int | None,
    seed: int,
    mcmc: bool,
    valve: str = "iso6358",
    friction: str = "auto",
) -> dict[str, Any]:
    """One campaign's fit, as run on a worker: plain, picklable inputs and result."""
    _single_threaded()
    from pneumafit.cli.fit import fit_command

    text = io.StringIO()
    console = LogConsole(file=text, force_terminal=False)  # each fit's log, tables in full
    t0 = time.perf_counter()
    try:
        # the parts of one's own that the command loaded (PNEUMAFIT_PARTS,
        # which --parts sets and a local cluster's workers inherit)
        from pneumafit.cli.plugins import load_parts

        load_parts()
        code = fit_command(Path(campaign), model, Path(out), walkers, steps, seed, mcmc, console,
                           valve=valve, friction=friction)  # fmt: skip
    except PneumafitInputError as exc:  # a parts file this worker cannot load
        console.print(f"error: {exc}")
        code = EXIT_BAD_INPUT
    except Exception as exc:  # a bug in one fit must not lose the others' results
        console.print(f"internal error: {type(exc).__name__}: {exc}")
        code = EXIT_FAILED
    log = text.getvalue()
    lines = [line for line in log.splitlines() if line.strip()]
    fit = os.path.join(out, "fit.json")
    return {
        "code": code,
        "fit": fit if code == EXIT_OK else None,
        "error": None if code == EXIT_OK else (lines[-1] if lines else f"exit status {code}"),
        "log": log,
        "seconds": time.perf_counter() - t0,
    }


def fit_many(
    campaigns: Sequence[Path],
    model: str,
    out: Path,
    *,
    seed: int = 0,
    mcmc: bool = True,
    walkers: int | None = None,
    steps: int | None = None,
    client: Client | None = None,
    console: Console | None = None,
    valve: str = "iso6358",
    friction: str = "auto",
) -> dict[Path, CampaignFit]:
    """Fit one model to many campaigns, one task per campaign.

    Parameters
    ----------
    campaigns : sequence of Path
        Campaign folders (or their campaign.toml); their folder names must
        differ (each names its output folder).
    model : str
        As for ``pneumafit fit``.
    out : Path
        Each campaign's fit goes to ``OUT/<campaign folder name>/``
        (``fit.json``, ``chains.h5``; resumable as with ``pneumafit fit``).
    seed : int
        Every campaign is fitted with this seed: its result is the one
        ``pneumafit fit CAMPAIGN --seed SEED`` gives.
    mcmc : bool
    walkers, steps : int or None
    client : distributed.Client, optional
        Runs the tasks on its cluster; None fits the campaigns one after the
        other in this process.
    console : rich.console.Console, optional
        One line per campaign as it completes (default: none printed).
    valve, friction : str
        As ``pneumafit fit --valve``, ``--friction`` (a law of one's own
        too: the workers load the command's ``--parts``).

    Returns
    -------
    dict of Path to CampaignFit
        In the order of ``campaigns``.

    Raises
    ------
    PneumafitInputError
        No campaign, or two campaigns with the same folder name.
    """
    campaigns = _check_campaigns(campaigns, out)
    jobs = {
        c: (os.fspath(c), model, os.fspath(Path(out) / _campaign_name(c)), walkers, steps,
            seed, mcmc, valve, friction)
        for c in campaigns
    }  # fmt: skip
    results: dict[Path, CampaignFit] = {}
    total = len(campaigns)

    def done(c: Path, r: dict[str, Any]) -> None:
        fit = CampaignFit(
            campaign=c, code=int(r["code"]), fit=Path(r["fit"]) if r["fit"] else None,
            error=r["error"], log=r["log"], seconds=float(r["seconds"]),
        )  # fmt: skip
        results[c] = fit
        if console is not None:
            what = f"wrote {fit.fit}" if fit.code == EXIT_OK else f"failed: {fit.error}"
            style = None if fit.code == EXIT_OK else "bold red"
            console.print(
                Text(f"[{len(results)}/{total}] {_campaign_name(c)} ({fit.seconds:.1f} s): "
                     f"{what}", style=style or "")
            )  # fmt: skip

    if client is None:
        for c in campaigns:
            done(c, _fit_one(*jobs[c]))
    else:
        from distributed import as_completed

        futures = {
            client.submit(_fit_one, *jobs[c], pure=False, key=f"fit-{_campaign_name(c)}-{i}"): c
            for i, c in enumerate(campaigns)
        }
        try:
            for future in as_completed(list(futures)):
                done(futures[future], future.result())
        except KeyboardInterrupt:
            client.cancel(list(futures))
            raise
    return {c: results[c] for c in campaigns}


def fit_many_command(
    campaigns: Sequence[Path],
    model: str,
    out: Path,
    *,
    scheduler: str | None,
    workers: int | None,
    seed: int,
    mcmc: bool,
    walkers: int | None,
    steps: int | None,
    console: Console,
    valve: str = "iso6358",
    friction: str = "auto",
) -> int:
    """Body of ``pneumafit fit-many``: the campaigns' fits on a Dask cluster.

    Returns
    -------
    int
        0 every fit succeeded, 1 some fit failed, 2 bad input (an
        unreachable scheduler, bad options, duplicate campaign names; and a
        campaign with bad input when no fit failed otherwise).
    """
    from pneumafit.cli.fit import law_problems
    from pneumafit.models.structure import MODELS

    # what is wrong for every campaign is said once, before starting a cluster
    problems = []
    try:
        _check_campaigns(campaigns, out)
    except PneumafitInputError as exc:
        problems.append(str(exc))
    if model not in MODELS:
        problems.append(f"option --model: expected one of {', '.join(MODELS)}, found {model!r}")
    problems += law_problems(valve, friction)
    problems += [int_problem("--walkers", walkers, 1), int_problem("--steps", steps, 1),
                 int_problem("--seed", seed, 0)]  # fmt: skip
    problems.append(folder_problem(out))
    if report_problems(console, problems):
        return EXIT_BAD_INPUT
    if workers is None and scheduler is None:
        workers = max(1, min(len(campaigns), os.cpu_count() or 1))
    try:
        with dask_client(scheduler, workers) as client:
            where = scheduler or f"a local cluster of {workers} worker processes"
            console.print(f"fitting {model} to {len(campaigns)} campaigns on {where}")
            results = fit_many(
                campaigns, model, out, seed=seed, mcmc=mcmc, walkers=walkers, steps=steps,
                client=client, console=console, valve=valve, friction=friction,
            )  # fmt: skip
    except PneumafitInputError as exc:
        console.print(Text(str(exc), style="bold red"))
        return EXIT_BAD_INPUT
    codes = [r.code for r in results.values()]
    ok = sum(c == EXIT_OK for c in codes)
    console.print(f"{ok} of {len(codes)} fits written under {os.fspath(out)}")
    if ok == len(codes):
        return EXIT_OK
    return EXIT_FAILED if any(c not in (EXIT_OK, EXIT_BAD_INPUT) for c in codes) else EXIT_BAD_INPUT


# ---------------------------------------------------------------- log posterior


class DaskPool:
    """A ``pool`` whose ``map`` runs on a Dask cluster (emcee's pool interface).

    Parameters
    ----------
    client : distributed.Client

    Notes
    -----
    emcee uses a pool only with ``vectorize=False``; our sampler is
    vectorised, so :func:`run_mcmc` takes a :class:`DistributedLogProb`
    instead. The pool is for per-set callables.
    """

    def __init__(self, client: Client) -> None:
        self.client = client

    def map(self, func: Callable[[Any], Any], iterable: Iterable[Any]) -> list[Any]:
        """``[func(x) for x in iterable]``, evaluated on the workers, in order."""
        items = list(iterable)
        if not items:
            return []
        futures = self.client.map(func, items, pure=False)
        return list(self.client.gather(futures))


def _evaluate(log_prob: Callable[[NDArray[np.float64]], ArrayLike], z: NDArray[np.float64]) -> Any:
    _single_threaded()
    return np.asarray(log_prob(z), dtype=float)


class DistributedLogProb:
    """A batched log posterior evaluated in chunks on a Dask cluster.

    Callable on a batch ``z`` (n_sets, n_free), returning (n_sets,), like
    the log posterior it wraps: pass it to :func:`run_mcmc` as ``log_prob``.
    The wrapped object is pickled (cloudpickle) once and broadcast to every
    worker; each call sends only the chunks of ``z``.

    Parameters
    ----------
    log_prob : callable
        Vectorised log posterior, picklable (a
        :class:`~pneumafit.identification.likelihood.LogPosterior` is: its
        compiled simulators are numba dispatchers, which pickle by reference
        and load the on-disk cache on the worker).
    client : distributed.Client
    chunks : int, optional
        Chunks per batch (default: the number of workers).
    """

    def __init__(
        self,
        log_prob: Callable[[NDArray[np.float64]], ArrayLike],
        client: Client,
        chunks: int | None = None,
    ) -> None:
        if chunks is not None and chunks < 1:
            raise PneumafitInputError(f"chunks: expected an integer >= 1, found {chunks!r}")
        self.client = client
        self.chunks = chunks or max(1, len(client.scheduler_info().get("workers", {})))
        self._remote = client.scatter(log_prob, broadcast=True, hash=False)

    def __call__(self, z: ArrayLike) -> NDArray[np.float64]:
        batch = np.atleast_2d(np.asarray(z, dtype=float))
        parts = [p for p in np.array_split(batch, min(self.chunks, batch.shape[0])) if p.size]
        futures = [self.client.submit(_evaluate, self._remote, p, pure=False) for p in parts]
        return np.concatenate([np.atleast_1d(v) for v in self.client.gather(futures)])

    def close(self) -> None:
        """Release the broadcast copy on the workers."""
        self.client.cancel([self._remote])


def distributed_log_prob(
    log_prob: Callable[[NDArray[np.float64]], ArrayLike],
    client: Client,
    chunks: int | None = None,
) -> DistributedLogProb:
    """``log_prob`` evaluated in ``chunks`` chunks per batch on ``client``'s workers.

    See :class:`DistributedLogProb`.
    """
    return DistributedLogProb(log_prob, client, chunks)
