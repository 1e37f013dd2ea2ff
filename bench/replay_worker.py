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
Child process of :mod:`bench.replay_bench` that times one replay.

Runs what ``polarization-compass replay BAG --methods M --out DIR`` runs, with that command's
defaults (:class:`polarization_compass.replay.ReplayConfig`, the shipped error map, the default
topic map, figures written), through the core (:func:`polarization_compass.replay.replay_bag` and
:func:`~polarization_compass.replay.write_outputs`; nothing outside ``cli/`` imports ``cli/``). It
writes, to ``TIMES.json``, the wall clock (seconds since this process started its Python code) at
the start of the replay loop and after each frame, taken from the replay's progress callback, and
prints the command's first line (frames, recording, wall and CPU time).

Usage: ``python -m bench.replay_worker TIMES.json replay BAG --out DIR [--methods M]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

T0 = time.perf_counter()


def _parse(cli_args):
    """Read the ``replay`` arguments the bench passes (others are refused, not ignored)."""
    p = argparse.ArgumentParser(prog='bench.replay_worker TIMES.json replay')
    p.add_argument('command', choices=('replay',))
    p.add_argument('bag')
    p.add_argument('--methods', default='all')
    p.add_argument('--out', default='replay_out')
    return p.parse_args(cli_args)


def main(argv) -> int:
    times_path, args = argv[0], _parse(argv[1:])
    from polarization_compass.bag import load_topic_map
    from polarization_compass.replay import (
        default_error_map,
        replay_bag,
        ReplayConfig,
        write_outputs,
    )

    rec = {'imported_s': time.perf_counter() - T0, 'replay_start_s': None, 'frame_done_s': []}

    def clocked(k):
        rec['frame_done_s'].append(time.perf_counter() - T0)

    methods = (
        ()
        if args.methods.strip() == 'all'
        else tuple(m.strip() for m in args.methods.split(',') if m.strip())
    )
    try:
        config = ReplayConfig(methods=methods, error_map=default_error_map())
        topic_map = load_topic_map(None)
        rec['replay_start_s'] = time.perf_counter() - T0
        result = replay_bag(args.bag, config, topic_map, clocked)
        write_outputs(result, args.out, args.bag, plots=True)
        print(
            f'{args.bag}: {result.frames} frames, {result.bag_duration_s:.1f} s of recording in '
            f'{result.wall_s:.1f} s ({result.speed_x_real_time:.1f}x real time; '
            f'{result.cpu_s:.1f} s of CPU in {result.workers} thread(s), '
            f'{result.speed_x_real_time_cpu:.1f}x on one idle core)'
        )
    finally:
        rec['end_s'] = time.perf_counter() - T0
        with open(times_path, 'w') as f:
            json.dump(rec, f)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
