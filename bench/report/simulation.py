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

"""The simulator and solar-position sections."""

from __future__ import annotations

from .formatting import fmt, md_table, pass_fail, section


def simulator_section(sim) -> list[str]:
    lines, r = section('Simulator', sim)
    if r is None:
        return lines
    lines += [
        f'Camera {r["camera"]["width_px"]} x {r["camera"]["height_px"]}, tilted attitude, fixed '
        'sun. '
        '`stages` = pipeline stages that ran (instrumentation counts): undeclared effects never '
        'run.',
        '',
    ]
    rows = []
    for x in r['rows']:
        if x.get('status') != 'ok':
            rows.append([x['name'], '-', '-', '-', '-', x['status'][:60]])
            continue
        rows.append(
            [
                x['name'],
                x['pixels'],
                fmt(x['single_thread']['median_ms']),
                fmt(x['all_threads']['median_ms']),
                fmt(x.get('relative_to_full', {}).get('single_thread')),
                ', '.join(x['stages']),
            ]
        )
    lines += md_table(
        [
            'configuration',
            'pixels',
            'ms (1 thread)',
            'ms (all threads)',
            'x full (1 thread)',
            'stages',
        ],
        rows,
    )
    s = r.get('summary', {})
    if s.get('targets'):
        lines += [
            '',
            "Issue 2's targets (full 2448 x 2048 frame; the stages alone are "
            '`sensor.simulate_mosaic` '
            'and `demosaic.polarization_from_mosaic` timed on their own):',
            '',
        ]
        lines += md_table(
            [
                'target',
                'target (ms)',
                'ms (1 thread)',
                'pass (1 thread)',
                'ms (all threads)',
                'pass (all threads)',
            ],
            [
                [
                    t['target'],
                    f'<= {fmt(t["target_ms"])}',
                    fmt(t['single_thread_median_ms']),
                    pass_fail(t['pass_single_thread']),
                    fmt(t['all_threads_median_ms']),
                    pass_fail(t['pass_all_threads']),
                ]
                for t in s['targets']
            ],
        )
    if 'stride8_speedup_single_thread' in s:
        unpaired = s.get('stride8_speedup_unpaired_single_thread')
        lines += [
            '',
            'Stride 8 against full, paired (blocks of both renders within the same second, each '
            'in its '
            f'steady state): {fmt(s["stride8_speedup_single_thread"])}x faster on one thread '
            f'(target >= 30x: {s["stride8_at_least_30x_single_thread"]}), '
            f'{fmt(s.get("stride8_speedup_all_threads"))}x on all threads'
            + (
                f"; from the two rows' medians above, timed apart: {fmt(unpaired)}x."
                if unpaired
                else '.'
            ),
        ]
    return lines + ['']


def solar_section(sol) -> list[str]:
    lines, r = section('Solar position', sol)
    if r is None:
        return lines
    rows = []
    for model, x in r['models'].items():
        rows.append(
            [
                model,
                fmt(x['batch']['positions_per_s']),
                fmt(x['per_call']['median_ms']),
                fmt(x.get('cache_per_frame', {}).get('median_ms')),
                fmt(x.get('cache_per_frame', {}).get('speedup_vs_per_call')),
            ]
        )
    lines += md_table(
        [
            'model',
            f'batch ({r["batch_size"]} times), positions/s',
            'per call (ms)',
            'SunCache per frame (ms)',
            'cache speed-up',
        ],
        rows,
    )
    g = r.get('paper_vs_spa_great_circle_deg', {})
    lines += [
        '',
        f'`paper` against `spa` over the batch (sun up): mean {fmt(g.get("mean"))} deg, '
        f'max {fmt(g.get("max"))} deg great-circle.',
    ]
    return lines + ['']
