"""An interrupted ``pneumafit fit`` says what is kept, and it is so (issue 17)."""

from __future__ import annotations

from pathlib import Path

import h5py
import pytest
from rich.console import Console

from pneumafit.cli.fit import fit_command
from pneumafit.services import fit as fit_module


def _interrupt_after(steps: int):
    """An ``identify`` that stores ``steps`` MCMC steps of the heat stage, then is
    interrupted (Ctrl-C)."""

    def identify(*_args: object, chains: Path | None = None, **_kw: object) -> None:
        if chains is not None and steps:
            with h5py.File(chains, "a") as f:
                f.create_group("heat").attrs["iteration"] = steps
        raise KeyboardInterrupt

    return identify


@pytest.mark.parametrize(
    ("mcmc", "steps", "said"),
    [
        (False, 0, "interrupted: nothing is kept (a fit with --no-mcmc stores no intermediate "
                   "state); the same command starts again from the beginning"),
        (True, 0, "interrupted before any MCMC step was stored: nothing is kept"),
        (True, 40, "interrupted: the MCMC chains sampled so far are kept in"),
    ],
)  # fmt: skip
def test_the_interruption_message_says_what_is_kept(
    small: tuple, tmp_path: Path, console: Console, monkeypatch: pytest.MonkeyPatch,
    mcmc: bool, steps: int, said: str,
) -> None:  # fmt: skip
    folder, _, _ = small
    monkeypatch.setattr(fit_module, "identify", _interrupt_after(steps))
    out = tmp_path / "fit"
    code = fit_command(folder, "convection", out, 8, 12, 7, mcmc, console)
    text = " ".join(console.file.getvalue().split())
    assert code == 130
    assert said in text
    assert "resume" not in text or steps > 0  # "resume" only where something is resumed
    assert not (out / "fit.json").exists()
    partial = out / "chains.partial.h5"
    if steps:
        assert "heat 40 steps" in text and "resumes the chains where they stopped" in text
        with h5py.File(partial, "r") as f:  # what the message says is kept is there
            assert f["heat"].attrs["iteration"] == steps
    if not mcmc:
        assert not partial.exists() and not any(out.iterdir())
