"""``python -m pneumafit``: the command line, as the ``pneumafit`` script runs it."""

from pneumafit.cli import main

if __name__ == "__main__":
    main()
