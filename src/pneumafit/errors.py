"""The errors pneumafit raises, one family: catch :class:`PneumafitError` for all.

- :class:`PneumafitInputError` (also a ``ValueError``): input that is not
  acceptable (a file, a key, a channel, an option, a value), its message
  naming where, what was expected and what was found. The command line prints
  it without a traceback and exits with status 2. Campaign validation raises
  its subclass :class:`pneumafit.campaign.errors.CampaignError` with every
  problem found.
- :class:`PneumafitComputationError` (also a ``RuntimeError``): the work
  failed on acceptable input (a simulation that diverged, a stage of the main
  job, the virtual rig). The command line exits with status 1.

This module imports nothing from pneumafit: every layer may raise these.
"""

from __future__ import annotations

__all__ = ["PneumafitComputationError", "PneumafitError", "PneumafitInputError"]


class PneumafitError(Exception):
    """Any error pneumafit raises on purpose."""


class PneumafitInputError(PneumafitError, ValueError):
    """Input given to pneumafit (a file, a value, an array) is not acceptable."""


class PneumafitComputationError(PneumafitError, RuntimeError):
    """The work failed on acceptable input (a simulation, a fit stage, the virtual rig)."""
