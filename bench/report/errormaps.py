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

"""The error-map sections: sweep throughput against issue 4's target and the sampling check."""

from __future__ import annotations

from .formatting import fmt, md_table, pass_fail, section


def errormap_section(em) -> list[str]:
    lines, r = section("Error map throughput against issue 4's target", em)
    if r is None:
        return lines
    if 'rows' in r:  # written before the target sweep was measured
        return lines + [
            'Results in an older format (no projection of the target sweep): rerun '
            '`python -m bench.run --only errormap`.',
            '',
        ]
    lines += _errormap_target_lines(r)
    b = r.get('backends')
    if b:
        lines += _errormap_backend_lines(b)
    return lines


def _errormap_target_lines(r) -> list[str]:
    """Return the measured throughput against the target sweep, with the knobs and the note."""
    lines = []
    t, smp = r['target'], r['sample']
    lines += [
        f'Target: a pitch-only sweep of {t["cells"]} cells (sun {t["sun_altitude_deg"]}, yaw '
        f'{t["yaw_deg"]}, '
        f'pitch {t["pitch_deg"]}, roll {t["roll_deg"]} deg) x {len(r["methods"])} methods = '
        f'{t["estimates"]} '
        f'estimates in <= {fmt(t["limit_s"])} s on all cores. Measured: the engine on a sub-grid '
        'of the same '
        f'domain ({len(smp["sun_altitude_deg"])} sun altitudes x {len(smp["pitch_deg"])} pitches '
        'x '
        f'{smp["yaw_count"]} yaws = {smp["cells"]} cells, {smp["estimates"]} estimates), '
        f'{r["workers"]} '
        f'workers, load average {fmt(r["load_average_before"][0])} -> '
        f'{fmt(r["load_average_after"][0])}.',
        '',
    ]
    lines += md_table(
        [
            'workers',
            'start-up (s)',
            'wall (s)',
            'cells/s',
            'estimates/s',
            'CPU ms per cell',
            f'projected {t["cells"]}-cell sweep (s)',
            f'<= {fmt(t["limit_s"])} s',
        ],
        [
            [
                r['workers'],
                fmt(r['startup_s']),
                fmt(r['wall_s']),
                fmt(r['cells_per_s']),
                fmt(r['estimates_per_s']),
                fmt(r['cpu_ms_per_cell']),
                fmt(r['projected_target_sweep_s']),
                pass_fail(r['pass']),
            ]
        ],
    )
    lines += [
        '',
        'Knobs: '
        + '; '.join(f'{m} {k} ({r["pixels"].get(m, "?")} px)' for m, k in r['knobs'].items()),
        '',
        f'{r["note"]}.',
        '',
    ]
    return lines


def _errormap_backend_lines(b) -> list[str]:
    """Return the comparison of the sweep backends (issue 17) and their projection."""
    lines = []
    smp = b['sample']
    lines += [
        f'Backends (issue 17) on a sub-grid of {smp["cells"]} cells in {smp["chunks"]} chunks '
        f'({len(smp["sun_altitude_deg"])} sun altitudes x {len(smp["pitch_deg"])} pitches x '
        f'{smp["yaw_count"]} yaws), load average {fmt(b["load_average_before"][0])} -> '
        f'{fmt(b["load_average_after"][0])}; maps identical to the in-process one: '
        f'{"yes" if b["identical_maps"] else "NO"}.',
        '',
    ]
    lines += md_table(
        [
            'backend',
            'workers',
            'start-up (s)',
            'compute (s)',
            'cells/s',
            'tasks/s',
            'overhead share',
            'CPU ms per estimate',
        ],
        [
            [
                x['backend'],
                x['workers'],
                fmt(x['startup_s']),
                fmt(x['compute_s']),
                fmt(x['cells_per_s']),
                fmt(x['tasks_per_s']),
                fmt(x['overhead_share']),
                fmt(x['cpu_ms_per_estimate']),
            ]
            for x in b['rows']
        ],
    )
    proj = ', '.join(
        f'{n} workers {fmt(v / 3600)} h' for n, v in b['projection_1e8_estimates_s'].items()
    )
    lines += [
        '',
        'Scaling 1 -> 2 workers (LocalCluster): efficiency '
        f'{fmt(b["scaling_efficiency_1_to_2"])}; '
        'one LocalCluster worker / in process: '
        f'{fmt(b["localcluster_per_worker_vs_in_process"])}. '
        f'Projected 10^8-estimate map: {proj}. {b["note"]}.',
        '',
    ]
    return lines


def errormap_sampling_section(es) -> list[str]:
    lines, r = section('Error map sampling against full resolution (issue 4)', es)
    if r is None:
        return lines
    lines += [
        f'{r["cells"]} random cells ({r["domain"]}; seed {r["seed"]}, camera {r["camera"]}): the '
        'error a map '
        'stores at the default sweep sampling against full resolution; target < '
        f'{fmt(r["target_deg"])} deg.',
        '',
    ]
    rows = [
        [
            m,
            f'{v["knobs_default"]} ({v["pixels_default"]} px)',
            f'{v["knobs_full"]} ({v["pixels_full"]} px)',
            fmt(v['max_abs_diff_deg']),
            fmt(v['mean_abs_diff_deg']),
            f'{v["cells_compared"]} / {r["cells"]}',
            v['status_differs'],
            pass_fail(v['pass']),
        ]
        for m, v in r['per_method'].items()
    ]
    lines += md_table(
        [
            'method',
            'default sampling',
            'full resolution',
            'max abs diff (deg)',
            'mean abs diff (deg)',
            'cells compared',
            'status differs',
            f'< {fmt(r["target_deg"])} deg',
        ],
        rows,
    )
    return lines + ['', f'{r["note"]}.', '']
