"""``python -m pneumafit`` and the installed ``pneumafit`` script: the command line.

``pneumafit --version`` alone is answered here, before the app
(:mod:`pneumafit.cli`, and the model registry it builds its choices from) is
imported, so that it costs what the interpreter's start costs.
"""

import sys


def main() -> None:
    """Run the command line (:func:`pneumafit.cli.main`)."""
    if sys.argv[1:] == ["--version"]:
        from pneumafit import __version__

        print(f"pneumafit {__version__}")
        return
    from pneumafit.cli import main as run

    run()


if __name__ == "__main__":
    main()
