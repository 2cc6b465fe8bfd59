"""The ``geoblock`` command line: a click group, one module per command.

* :mod:`geoblock.cli.main` builds the group (:func:`~geoblock.cli.main.build_cli`), adds the
  built-in commands, then the plugins' commands through the ``geoblock_register_commands``
  hook, and turns errors and warnings into one line each on standard error.
* :mod:`geoblock.cli.options` holds the arguments and options shared by several commands.
* One module per built-in command, imported when the command runs (``geoblock --help`` lists
  them from :data:`~geoblock.cli.main.BUILTIN_COMMANDS` without importing them):
  :mod:`~geoblock.cli.plugins`, :mod:`~geoblock.cli.info`,
  :mod:`~geoblock.cli.project` (``project`` and ``backproject``), :mod:`~geoblock.cli.localize`,
  :mod:`~geoblock.cli.dem_info`, :mod:`~geoblock.cli.refine`, :mod:`~geoblock.cli.adjust`,
  :mod:`~geoblock.cli.ortho`, :mod:`~geoblock.cli.mosaic`, :mod:`~geoblock.cli.match`,
  :mod:`~geoblock.cli.simulate` and :mod:`~geoblock.cli.demo`.

Nothing here opens files itself: paths go to :mod:`geoblock.io`.
"""

__all__: list[str] = []
