"""``python -m geoblock.cli``: the ``geoblock`` command line without the console script."""

from geoblock.cli.main import main

if __name__ == "__main__":  # pragma: no branch
    main()
