"""The command line: every command's body and its console output.

The layer above the services: each module parses and checks a command's
options, calls the services of the domain packages (which return objects or
raise :mod:`pneumafit.errors` exceptions), prints what they found and turns
their ends into exit statuses.

- :mod:`.app`: the typer app (``pneumafit ...``) and :func:`main`, the
  installed ``pneumafit`` script and ``python -m pneumafit``.
- :mod:`.console`: what every command shares: exit statuses, option
  problems, the log console, ``--quiet`` / ``--verbose``.
- :mod:`.fit`, :mod:`.compare`, :mod:`.discover`, :mod:`.rig`: the bodies of
  ``pneumafit fit``, ``compare``, ``discover`` and ``rig``.
- :mod:`.friction`, :mod:`.friction_discover`: ``fit`` and ``discover`` on a
  campaign of friction tests (dispatched there by :mod:`.fit` and
  :mod:`.discover`).
"""

from pneumafit.cli.app import app, main

__all__ = ["app", "main"]
