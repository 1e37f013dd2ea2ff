# Copyright 2026 polarization_compass developers
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
`polarization-compass` command line: a thin adapter over the core library.

Each subcommand lives in its own module ``cli/cmd_<name>.py`` exposing ``register(subparsers)``,
which adds a parser and sets ``func`` (taking the parsed args, returning an exit code). Add a new
command by adding its module name to ``COMMANDS``.

Errors meant for users (:class:`~polarization_compass.errors.CompassError`, bad files, and what an
input causes: a RecursionError, a MemoryError, an OpenCV error) print one line and exit 2; an
unexpected exception prints one line naming it and exits 70 (``--debug`` shows the traceback).
Ctrl-C prints one line and exits 130, SIGTERM the same (exit 143), both unwinding the command so
its files are closed (``record-sim`` writes the bag's metadata). Python warnings are one line each.
No traceback reaches a user by default.
"""

from __future__ import annotations

import argparse
from contextlib import contextmanager
import importlib
import os
import signal
import sys
import threading

from ..errors import CompassError

COMMANDS = [
    'sun',
    'render',
    'estimate',
    'errormap',
    'allowable_tilt',
    'plot',
    'sim',
    'record_sim',
    'replay',
    'estimate_array',
    'calibrate_array',
    'calibrate_mount',
    'check_array',
    'budget',
    'check_polarizer',
]


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line and exit status 2."""

    def error(self, message):  # one line, exit 2, no usage dump
        self.exit(2, f'{self.prog}: error: {message}\n')


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog='polarization-compass',
        description='Heading from skylight polarization: simulate, estimate, map tilt errors, '
        'correct.',
    )
    p.add_argument('--debug', action='store_true', help='show tracebacks of unexpected errors')
    sub = p.add_subparsers(dest='command', metavar='COMMAND', parser_class=_Parser)
    for name in COMMANDS:
        try:
            mod = importlib.import_module(f'{__name__}.cmd_{name}')
        except ModuleNotFoundError as exc:
            if exc.name == f'{__name__}.cmd_{name}':
                continue  # command not built yet
            raise
        mod.register(sub)
    return p


class _Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the command is so that it unwinds (closes its files) as on Ctrl-C."""


def _raise_terminated(signum, frame):
    raise _Terminated


@contextmanager
def _one_line_process(command: str):
    """
    Run a command with SIGTERM unwinding like SIGINT and third-party noise folded or silenced.

    Python warnings (numpy's RuntimeWarnings with their source paths) become one line each, once;
    asyncio's "Task was destroyed" at exit (a Dask client's leftovers) is silenced.
    """
    import logging
    import warnings

    logging.getLogger('asyncio').setLevel(logging.CRITICAL)
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _raise_terminated) if main_thread else None
    seen = set()

    def one_line(message, category, *_args, **_kw):
        text = f'{category.__name__}: {" ".join(str(message).split())}'
        if text not in seen:
            seen.add(text)
            print(f'polarization-compass {command}: warning: {text}', file=sys.stderr)

    with warnings.catch_warnings():
        warnings.showwarning = one_line
        try:
            yield
        finally:
            if main_thread:
                signal.signal(signal.SIGTERM, previous)


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, 'func', None):
        parser.print_help()
        return 2
    try:
        with _one_line_process(args.command):
            return int(args.func(args) or 0)
    except CompassError as exc:
        print(f'polarization-compass {args.command}: error: {exc}', file=sys.stderr)
        return 2
    except BrokenPipeError:
        # the reader went away (e.g. `| head`): not an error of ours; silence the flush at exit
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except OSError:
            pass
        return 141
    except OSError as exc:
        if (
            exc.filename is not None
        ):  # a path the user gave: not found, a directory, not writable ...
            print(
                f'polarization-compass {args.command}: error: {exc.strerror or exc}: '
                f'{exc.filename}',
                file=sys.stderr,
            )
            return 2
        return _internal_error(args, exc)
    except _Terminated:
        print(f'polarization-compass {args.command}: terminated', file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print(f'polarization-compass {args.command}: interrupted', file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - last line of defence: no traceback for users
        return _input_error(args, exc)


def entry() -> int:
    """
    Run the console command: :func:`main`, then no second Ctrl-C during the interpreter's shutdown.

    Once an interrupt or SIGTERM has been reported (exit 130 or 143), the process is on its way
    out; a further Ctrl-C (a terminal's repeated key, a supervisor signalling the process group)
    would otherwise land in Python's shutdown and end the process by SIGINT instead of the exit
    status just reported. :func:`main` itself leaves signal handlers alone (tests call it in
    process).
    """
    status = main()
    if status in (130, 143) and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    return status


def _input_error(args, exc) -> int:
    """Report what the input caused (too deep, too large, undecodable) as a user error, exit 2."""
    if isinstance(exc, RecursionError):
        why = 'the input is nested too deeply to read (RecursionError)'
    elif isinstance(exc, MemoryError):
        why = 'not enough memory for this input (MemoryError); is it the right file?'
    elif type(exc).__module__.startswith('cv2') and type(exc).__name__ == 'error':
        lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
        why = f'OpenCV cannot process the input ({lines[-1][:200] if lines else "cv2.error"})'
    else:
        return _internal_error(args, exc)
    if args.debug or os.environ.get('POLARIZATION_COMPASS_DEBUG'):
        raise exc
    print(f'polarization-compass {args.command}: error: {why}', file=sys.stderr)
    return 2


def _internal_error(args, exc) -> int:
    if args.debug or os.environ.get('POLARIZATION_COMPASS_DEBUG'):
        raise exc
    print(
        f'polarization-compass {args.command}: internal error: {type(exc).__name__}: {exc} '
        f'(run with --debug for the traceback)',
        file=sys.stderr,
    )
    return 70
