"""The ``gyro-rotor`` command line: ``main(argv) -> int``; one module per subcommand.

Subcommands live in :mod:`gyro_rotor.cli.commands` (``add_arguments`` and ``run``); this
module only dispatches and turns a :class:`~gyro_rotor.errors.GyroRotorError`, or a bad
command-line argument (argparse's usage errors, :class:`_Parser`), into one ``ERROR: ...``
line on stderr and exit status 1 (``--help`` exits 0). Exit status 2 is left to the
commands' own meaning (``locus``: a claim failed; ``analyze``: a verdict not confirmed;
``simulate``: the run diverged or grew).

A signal ends a command with ``interrupted`` (SIGINT) or ``terminated`` on stderr and the
shell's status 128 + its number (130 for Ctrl-C), never with a traceback: also where
rclpy's C code turned the KeyboardInterrupt into another exception (the handler installed
here remembers the Ctrl-C, :class:`~gyro_rotor.signals.StopSignals`), and where a command
acts on a signal at a loop boundary of its own (:class:`~gyro_rotor.signals.Stopped`).
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys

from gyro_rotor.cli.util import error_hint
from gyro_rotor.errors import GyroRotorError
from gyro_rotor.signals import exit_status, StopSignals

#: subcommand name -> module in gyro_rotor.cli.commands (listed in the order of --help)
COMMANDS = {
    'demo': 'demo',
    'simulate': 'simulate',
    'steady': 'steady',
    'scenes': 'scenes',
    'eig': 'eig',
    'locus': 'locus',
    'tune': 'tune',
    'bench': 'bench',
    'analyze': 'analyze',
    'monitor': 'monitor',
    'recover': 'recover',
    'soak': 'soak',
    'rt-bench': 'rt_bench',
    'campbell': 'campbell',
    'sweep': 'sweep',
    'sweep-bench': 'sweep_bench',
}


class UsageError(GyroRotorError):
    """A bad command-line argument (argparse's message and the command it belongs to)."""


class _Parser(argparse.ArgumentParser):
    """An argparse parser whose usage errors raise :class:`UsageError` (not exit 2).

    ``add_subparsers`` builds the subcommands' parsers with the class of their parent, so
    every subcommand reports a bad argument the same way.
    """

    def error(self, message: str):
        """Raise :class:`UsageError` with argparse's message, naming ``--help``."""
        raise UsageError(f'{message} (see {self.prog} --help)')


def _load(name: str):
    """Import the module of subcommand ``name`` (a registered command must exist)."""
    return importlib.import_module(f'gyro_rotor.cli.commands.{COMMANDS[name]}')


#: options that name an output file or directory
_PATH_OPTIONS = ('out', 'json', 'csv')


def build_parser() -> argparse.ArgumentParser:
    """Build the argparse parser with every available subcommand."""
    parser = _Parser(
        prog='gyro-rotor',
        description='Magnus (1980) gyrostat on a synchronous drive: simulate, analyse, '
                    'record, demo.')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND')
    sub.required = True
    for name in COMMANDS:
        mod = _load(name)
        p = sub.add_parser(name, help=mod.HELP, description=mod.HELP)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    interrupt = StopSignals((signal.SIGINT,), at_once=True).install()
    try:
        return _main(argv)
    except KeyboardInterrupt as err:
        return _stopped(getattr(err, 'signum', signal.SIGINT))
    except Exception:  # noqa: B902 -- only the interrupt's, as the test below says
        if not interrupt.requested:
            raise
        return _stopped(interrupt.signum)      # rclpy made another exception of it
    finally:
        interrupt.restore()


def _stopped(signum: int) -> int:
    print('interrupted' if signum == signal.SIGINT else 'terminated', file=sys.stderr)
    return exit_status(signum)


def _main(argv: list[str] | None) -> int:
    parser = build_parser()
    try:
        args, extra = parser.parse_known_args(argv)
        if extra:       # as parse_args, but naming the command they were given to
            raise UsageError(f'unrecognized arguments: {" ".join(extra)} '
                             f'(see {parser.prog} {args.command} --help)')
        for name in _PATH_OPTIONS:      # '' would be skipped as "not given", in silence
            if getattr(args, name, None) == '':
                raise UsageError(f'--{name} is empty: give a file name')
    except UsageError as err:
        print(f'ERROR: {err}', file=sys.stderr)
        return 1
    try:
        status = int(args._run(args) or 0)
        sys.stdout.flush()      # inside the try: a closed pipe is handled below
        return status
    except GyroRotorError as err:
        print(f'ERROR: {err}{error_hint(err)}', file=sys.stderr)
        return 1
    except BrokenPipeError:
        # the reader of stdout went away (`gyro-rotor ... | head`): not an error of ours.
        # As the Python docs advise: point stdout at devnull so that the flush at exit does
        # not fail again, and exit quietly.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 1
    except (OSError, UnicodeError) as err:
        # a file that cannot be read or written (missing directory, a directory instead of
        # a file, no permission, disk full): the message names the path
        print(f'ERROR: {err}', file=sys.stderr)
        return 1
    except (OverflowError, MemoryError) as err:
        print(f'ERROR: the numbers asked for are too large: {type(err).__name__}: {err}',
              file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
