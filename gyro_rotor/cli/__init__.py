"""The ``gyro-rotor`` command and its subcommands."""
