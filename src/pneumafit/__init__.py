"""pneumafit."""

from importlib import metadata as _metadata

try:
    __version__: str = _metadata.version("pneumafit")
except _metadata.PackageNotFoundError:  # running from a source tree without install
    __version__ = "unknown"

__all__ = ["__version__"]
