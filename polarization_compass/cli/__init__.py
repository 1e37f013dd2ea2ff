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

Errors meant for users (:class:`~polarization_compass.errors.CompassError`, bad files) print one
line and exit 2; an unexpected exception prints one line naming it and exits 70 (``--debug``
shows the traceback). No traceback reaches a user by default.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

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


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, 'func', None):
        parser.print_help()
        return 2
    try:
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
    except KeyboardInterrupt:
        print(f'polarization-compass {args.command}: interrupted', file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - last line of defence: no traceback for users
        return _internal_error(args, exc)


def _internal_error(args, exc) -> int:
    if args.debug or os.environ.get('POLARIZATION_COMPASS_DEBUG'):
        raise exc
    print(
        f'polarization-compass {args.command}: internal error: {type(exc).__name__}: {exc} '
        f'(run with --debug for the traceback)',
        file=sys.stderr,
    )
    return 70
