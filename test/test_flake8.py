"""ament_flake8 over the repository, as in the ros2/examples ament_python template.

ament_flake8 brings its own configuration (max-line-length 99, google import order with
gyro_rotor treated as third party, single quotes, flake8-docstrings with the ament ignores)
and lints the current directory recursively, skipping folders whose names start with '.' or
'_' (.venv, __pycache__). The test therefore runs from the repository root whatever the
cwd of pytest, and excludes colcon's and the demo's output folders.
"""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
EXCLUDE = ['build', 'install', 'log', 'demo_runs', 'bench_out', 'bags_out', 'out']


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8(monkeypatch):
    main_with_errors = pytest.importorskip('ament_flake8.main').main_with_errors
    monkeypatch.chdir(ROOT)
    rc, errors = main_with_errors(argv=['--exclude', *EXCLUDE])
    assert rc == 0, \
        'Found %d code style errors / warnings:\n' % len(errors) + \
        '\n'.join(errors)
