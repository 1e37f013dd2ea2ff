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
Entry point: ``python -m bench.run [--quick] [--only NAME,...] [--out DIR] [--peers-python PATH]``.

Runs the benchmark groups (see :data:`bench.GROUPS`), writes ``<out>/<group>.json`` for each (with
the machine, library versions, date, git commit and the load average at start and end), then
``summary.md`` and the plots (:mod:`bench.report`). A group whose code or dependency is not there
yet is recorded as ``unavailable`` with the reason; a group that raises is recorded as ``failed``
with the traceback, and the exit status is then 1.

``--quick`` checks the suite in under two minutes (few scenes, few knobs, peers at half size, a 3 s
replay; the ``graph`` group, which starts the 11-process ROS graph, is skipped unless named with
``--only graph``); the full mode is what the README numbers come from (about 20-40 minutes on 2
cores; run it when the machine is otherwise idle: the load average is recorded so a noisy run can
be recognised). A group that does not run in a mode is recorded as ``skipped`` with the reason.
"""

from __future__ import annotations

import argparse
import importlib
from pathlib import Path
import sys
import time
import traceback

from . import GROUPS
from .common import BenchConfig, load_average, machine_info, Skipped, Unavailable, write_json


def parse_args(argv=None):
    p = argparse.ArgumentParser(
        prog='python -m bench.run', description=__doc__.strip().split('\n\n')[0]
    )
    p.add_argument(
        '--quick', action='store_true', help='small configuration for checking (< 2 min)'
    )
    p.add_argument(
        '--only', default='', help=f'comma-separated groups out of: {", ".join(GROUPS)}'
    )
    p.add_argument('--out', default=None, help='results directory (default bench/results)')
    p.add_argument(
        '--peers-python',
        default=None,
        help='interpreter with pyskylumos/polanalyser installed (default $BENCH_PEERS_PYTHON)',
    )
    p.add_argument('--scenes', type=int, default=None, help='override scenes per condition')
    p.add_argument(
        '--error-map',
        default=None,
        help='error map for tilted_corrected (default $BENCH_ERROR_MAP, else the shipped map)',
    )
    p.add_argument(
        '--conditions', default='', help='comma-separated accuracy conditions (default all)'
    )
    p.add_argument(
        '--methods', default='', help='comma-separated methods (default all registered)'
    )
    p.add_argument('--tiny', action='store_true', help=argparse.SUPPRESS)  # smoke test size
    p.add_argument(
        '--no-report', action='store_true', help='do not rebuild summary.md and the plots'
    )
    return p.parse_args(argv)


def make_config(args) -> BenchConfig:
    kw = {}
    if args.out:
        kw['out_dir'] = Path(args.out)
    if args.peers_python:
        kw['peers_python'] = args.peers_python
    if args.error_map:
        kw['error_map'] = args.error_map
    if args.conditions:
        kw['conditions'] = tuple(c.strip() for c in args.conditions.split(',') if c.strip())
    if args.methods:
        kw['methods'] = tuple(m.strip() for m in args.methods.split(',') if m.strip())
    if args.only:
        kw['explicit_groups'] = tuple(n.strip() for n in args.only.split(',') if n.strip())
    if args.tiny:
        kw.update(tiny=True, scenes=2, repeats=1, render_repeats=2, speed_repeats=2)
    cfg = BenchConfig.quick(**kw) if (args.quick or args.tiny) else BenchConfig.full(**kw)
    if args.tiny:
        cfg.mode = 'tiny'
    if args.scenes is not None:
        cfg.scenes = int(args.scenes)
    return cfg


def run_group(name: str, cfg: BenchConfig, machine: dict) -> dict:
    """Run one group and write its JSON; returns the envelope."""
    load_start = load_average()
    t0 = time.perf_counter()
    envelope = {'benchmark': name, 'mode': cfg.mode, 'machine': machine, 'config': cfg.to_json()}
    try:
        mod = importlib.import_module(f'bench.{GROUPS[name]}')
        envelope['results'] = mod.run(cfg)
        envelope['status'] = 'ok'
    except Unavailable as exc:
        envelope['status'] = f'unavailable: {exc}'
        envelope['results'] = None
    except Skipped as exc:
        envelope['status'] = f'skipped: {exc}'
        envelope['results'] = None
    except Exception as exc:  # noqa: BLE001 - record and go on with the other groups
        envelope['status'] = f'failed: {type(exc).__name__}: {exc}'
        envelope['traceback'] = traceback.format_exc(limit=6)
        envelope['results'] = None
    envelope['elapsed_s'] = time.perf_counter() - t0
    envelope['load_average'] = {'start': load_start, 'end': load_average()}
    write_json(Path(cfg.out_dir) / f'{name}.json', envelope)
    return envelope


def main(argv=None) -> int:
    args = parse_args(argv)
    cfg = make_config(args)
    names = [n.strip() for n in args.only.split(',') if n.strip()] or list(GROUPS)
    unknown = [n for n in names if n not in GROUPS]
    if unknown:
        print(f'bench: unknown group(s) {unknown}; known: {", ".join(GROUPS)}', file=sys.stderr)
        return 2
    machine = machine_info()
    t0 = time.perf_counter()
    failed = False
    print(
        f'bench ({cfg.mode}): {", ".join(names)} -> {cfg.out_dir}  load {load_average()}',
        flush=True,
    )
    for name in names:
        env = run_group(name, cfg, machine)
        print(f'  {name:15s} {env["status"][:100]:100s} {env["elapsed_s"]:7.1f} s', flush=True)
        failed |= env['status'].startswith('failed')
    if not args.no_report:
        from . import report

        paths = report.build(cfg.out_dir)
        for p in paths:
            print(f'  wrote {p}')
    print(f'bench: done in {time.perf_counter() - t0:.1f} s, load {load_average()}', flush=True)
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
