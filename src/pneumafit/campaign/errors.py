"""Errors raised on bad campaign input, in the user's words.

Every problem names the file, the key or channel, what was expected and what
was found, so that a test engineer can fix the file without reading code.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal

from pneumafit.errors import PneumafitInputError

__all__ = ["CampaignError", "PneumafitInputError", "Problem", "Severity"]

Severity = Literal["error", "warning"]


# the one input error of every layer (pneumafit.errors), named here too as before


@dataclass(frozen=True)
class Problem:
    """One thing wrong (or suspicious) in a campaign.

    Parameters
    ----------
    file : str
        File name relative to the campaign folder, e.g. ``"campaign.toml"`` or
        ``"step_1.csv"``.
    key : str
        Key path in ``campaign.toml`` (``"rig.bore"``, ``"recording[2].kind"``,
        counted from 1 in file order) or channel / dataset name in a recording
        (``"p_P"``, ``"/time"``). Empty when the problem is about the whole file.
    expected : str
        What the format asks for, e.g. ``'a length (e.g. "32 mm")'``.
    found : str
        What was found instead, e.g. ``'"6 bar" (a pressure)'``.
    severity : {"error", "warning"}
        Errors make the campaign invalid; warnings are only reported.
    """

    file: str
    key: str
    expected: str
    found: str
    severity: Severity = "error"

    def __str__(self) -> str:
        where = f"{self.file}: {self.key}" if self.key else self.file
        return f"{where}: expected {self.expected}, found {self.found}"

    @property
    def is_error(self) -> bool:
        """True for an error, False for a warning."""
        return self.severity == "error"


class CampaignError(PneumafitInputError):
    """A campaign failed validation.

    Parameters
    ----------
    path : str
        The campaign folder (or file) that was read.
    problems : iterable of Problem
        Every problem found, errors and warnings.

    Attributes
    ----------
    problems : list of Problem
        Every problem found, errors first in file order, then warnings.
    errors : list of Problem
        The problems of severity ``"error"``.
    """

    def __init__(self, path: str, problems: Iterable[Problem]) -> None:
        self.path = path
        self.problems = list(problems)
        self.errors = [p for p in self.problems if p.is_error]
        n = len(self.errors)
        lines = "\n".join(f"  {p}" for p in self.errors)
        super().__init__(f"{path} is not a valid campaign ({n} error{'s' * (n != 1)}):\n{lines}")
