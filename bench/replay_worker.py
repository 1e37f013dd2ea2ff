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

Child process of :mod:`bench.replay_bench`: runs ``polarization-compass replay ARGS...`` (the
command line's own ``main``, so the same parser, defaults and outputs) and writes, to
``TIMES.json``, the wall clock (seconds since this process started its Python code) at the start of
the replay loop and after each frame, taken from the replay's progress callback. Nothing else is
changed.

Usage: ``python -m bench.replay_worker TIMES.json replay BAG --out DIR [options]``.
"""

from __future__ import annotations

import json
import sys
import time

T0 = time.perf_counter()


def main(argv) -> int:
    times_path, cli_args = argv[0], argv[1:]
    from polarization_compass import replay as rp
    from polarization_compass.cli import main as cli_main

    rec = {'imported_s': time.perf_counter() - T0, 'replay_start_s': None, 'frame_done_s': []}
    original = rp.replay_bag

    def timed_replay_bag(*args, **kwargs):
        progress = kwargs.pop('progress', args[3] if len(args) > 3 else None)
        args = args[:3]

        def clocked(k):
            rec['frame_done_s'].append(time.perf_counter() - T0)
            if progress is not None:
                progress(k)

        rec['replay_start_s'] = time.perf_counter() - T0
        return original(*args, progress=clocked, **kwargs)

    rp.replay_bag = timed_replay_bag
    try:
        code = cli_main(cli_args)
    finally:
        rp.replay_bag = original
        rec['end_s'] = time.perf_counter() - T0
        with open(times_path, 'w') as f:
            json.dump(rec, f)
    return code


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
