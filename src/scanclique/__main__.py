"""``python -m scanclique``: the same command as ``scanclique`` (see :mod:`scanclique.cli`)."""

from .cli import main

if __name__ == "__main__":
    main()
