"""``gyro-rotor demo`` stopped by Ctrl-C while its live table runs: 130, bag and report.

The demo's main thread spends its time in rclpy (its live view's executor taking and
deserializing messages). A SIGINT handler that raises there (a KeyboardInterrupt in
pybind11's conversion of a message) came out of the monitor as a ``TypeError`` traceback
and exit status 1 under load (ce52d5c); the demo must leave at its loop's boundaries
instead, stop the nodes, analyse the data up to the cut and return 130.
"""

import json
import signal
import sys

import node_helpers
import pytest

#: the bound on the whole run (a failure bound, not a pace: the test waits for events)
RUN_WITHIN_S = 300.0


def _is_row(line: str) -> bool:
    """Return whether a line of the demo's stdout is a data row of the live table."""
    return line[:9].strip().replace('.', '').isdigit()


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.parametrize('rows', [1, 3, 6])
def test_demo_ctrl_c_at_a_live_row_stops_cleanly_with_130(tmp_path, rows):
    """Ctrl-C at the ``rows``-th row of the live table: 130, no traceback, bag and report.

    SIGINT once the live table printed its ``rows``-th data row (the signal lands at a
    different point of the loop each time): exit 130, 'interrupted' on stderr, no
    traceback, the bag finalized and analysed up to the cut.
    """
    out = tmp_path / 'demo'
    seen = 0

    def on_line(line, p):
        nonlocal seen
        if _is_row(line):
            seen += 1
            if seen == rows:
                p.send_signal(signal.SIGINT)
    status, stdout, stderr = node_helpers.run_reading(
        [sys.executable, '-m', 'gyro_rotor', 'demo', '--rtf', '0', '--duration', '120',
         '--out', str(out)], on_line, RUN_WITHIN_S, tmp_path)
    both = stdout[-3000:] + '\n--- stderr ---\n' + stderr[-3000:]
    assert seen >= rows, f'the live table showed {seen} rows, the run ended first\n{both}'
    assert 'Traceback' not in stderr + stdout and 'TypeError' not in stderr + stdout, both
    assert status == 130, both
    assert 'interrupted: stopping the nodes, finalizing the bag' in stderr, both
    assert (out / 'bag').exists(), both
    report = json.loads((out / 'report' / 'report.json').read_text())
    assert report['verdict'], report
    assert 'interrupted (Ctrl-C)' in stdout, both
