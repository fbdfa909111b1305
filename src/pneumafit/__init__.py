"""pneumafit: identification and validation of electropneumatic actuator models.

From Python (:mod:`pneumafit.api`)::

    import pneumafit as pf

    campaign = pf.read_campaign("data/measured/NAP310")
    fit = pf.fit(campaign, "friction", mcmc=False)
    fit.save("out/NAP310/fit.json")
    print(pf.discover(campaign, fit).statement)

The names below are imported on first use, so ``import pneumafit`` (and the
command line's start) stays light.
"""

from importlib import metadata as _metadata
from typing import Any

from pneumafit.errors import PneumafitComputationError, PneumafitError, PneumafitInputError

try:
    __version__: str = _metadata.version("pneumafit")
except _metadata.PackageNotFoundError:  # running from a source tree without install
    __version__ = "unknown"

_API = (
    "FitResult", "SavedFit", "compare", "discover", "fit", "load_fit", "read_campaign", "report",
)  # fmt: skip

__all__ = [
    "PneumafitComputationError",
    "PneumafitError",
    "PneumafitInputError",
    "__version__",
    *_API,
]


def __getattr__(name: str) -> Any:
    if name in _API:
        from pneumafit import api

        return getattr(api, name)
    raise AttributeError(f"module 'pneumafit' has no attribute {name!r}")
