"""``python -m gyro_rotor``: the gyro-rotor command line."""

import sys

from gyro_rotor.cli.main import main

sys.exit(main())
