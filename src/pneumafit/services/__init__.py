"""Services: each job of the command line as a function that computes and
writes its result folder, and returns the result object.

Below the command line (:mod:`pneumafit.cli`) and the main job
(:mod:`pneumafit.pipeline`), above the domain packages and the outputs: a
service takes a campaign and options, writes its files atomically and
returns an object; it raises the :mod:`pneumafit.errors` family (bad input,
a failed computation) and lets ``KeyboardInterrupt`` through, and prints
nothing (it reports through the ``log`` and ``progress`` it is given). The
commands turn its results into console output and its errors into exit
statuses; the main job chains the services and renders their results with
the same functions as the commands.

- :mod:`pneumafit.services.fit`: ``fit_folder`` (``pneumafit fit``);
- :mod:`pneumafit.services.compare`: ``compare_folder`` (``pneumafit compare``);
- :mod:`pneumafit.services.discover`: ``discover_folder`` (``pneumafit discover``).
"""

from pneumafit.services.compare import compare_folder
from pneumafit.services.discover import discover_folder
from pneumafit.services.fit import fit_folder

__all__ = ["compare_folder", "discover_folder", "fit_folder"]
