"""The ``geoblock`` command line: a click group, one module per command.

* :mod:`geoblock.cli.main` builds the group (:func:`~geoblock.cli.main.build_cli`), adds the
  built-in commands, then the plugins' commands through the ``geoblock_register_commands``
  hook, and turns errors and warnings into one line each on standard error.
* :mod:`geoblock.cli.options` holds the arguments and options shared by several commands.
* :mod:`geoblock.cli.plugins`, :mod:`geoblock.cli.info` and :mod:`geoblock.cli.project` are the
  built-in commands (``plugins``, ``info``, ``project`` and ``backproject``).

Nothing here opens files itself: paths go to :mod:`geoblock.io`.
"""

__all__: list[str] = []
