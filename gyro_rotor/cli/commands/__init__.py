"""Subcommands of the ``gyro-rotor`` command line, one module each.

Each module defines ``add_arguments(parser)`` and ``run(args) -> int`` (an exit code),
prints and plots, and catches nothing: :func:`gyro_rotor.cli.main` turns a
``GyroRotorError`` into ``ERROR: ...`` and exit status 1.
"""
