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

"""The sections of the runs through ROS and the peers: offline replay, the ROS graph, peers."""

from __future__ import annotations

from .formatting import fmt, md_table, pass_fail, section


def replay_section(rp) -> list[str]:
    lines, r = section('Offline replay speed (issue 6)', rp)
    if r is None:
        return lines
    tgt = f'>= {r["target_x_real_time"]:g}x'
    lines += [
        f'`{r["record_command"]}` ({r["frames"]} frames, {fmt(r.get("bag_mib"))} MiB, recorded in '
        f'{fmt(r.get("record_s"))} s), then `{r["replay_command"]}` at its default knobs (the '
        'shipped '
        'error map, figures written).',
        '',
    ]
    rows = [
        [
            f'whole command ({fmt(r["bag_duration_s"])} s recording)',
            f'{fmt(r["whole_command_s"])} s',
            f'{fmt(r["whole_command_x_real_time"])}x',
            tgt,
            pass_fail(r['pass_whole_command']),
        ],
        [
            f'per frame after start-up (frames {r.get("skipped_frames")}..{r["frames"]})',
            f'{fmt(r.get("per_frame_ms"))} ms (median {fmt(r.get("per_frame_ms_median"))}, '
            f'p95 {fmt(r.get("per_frame_ms_p95"))})',
            f'{fmt(r.get("per_frame_x_real_time"))}x',
            tgt,
            pass_fail(r.get('pass_per_frame')),
        ],
        [
            '10-minute run (extrapolated: overhead + per-frame)',
            f'overhead {fmt(r.get("overhead_s"))} s',
            f'{fmt(r.get("long_run_x_real_time"))}x',
            tgt,
            pass_fail(r.get('pass_long_run')),
        ],
    ]
    lines += md_table(['measure', 'time', 'x real time', 'target', 'pass'], rows)
    runs = r.get('runs') or []
    if len(runs) > 1:
        lines += [
            '',
            f'The run with the median per-frame time of {len(runs)} replays of the same bag; per '
            'frame in '
            'each: '
            + ', '.join(
                f'{fmt(x.get("per_frame_ms"))} ms ({fmt(x.get("per_frame_x_real_time"))}x)'
                for x in runs
            )
            + '.',
        ]
    al = r.get('all_methods')
    if al:
        lines += [
            '',
            "The command's default method set (the four plus tilt_aware, "
            f'`{al["replay_command"]}`), '
            'replayed interleaved with the runs above: per frame '
            f'{fmt(al.get("per_frame_ms"))} ms '
            f'({fmt(al.get("per_frame_x_real_time"))}x; runs: '
            + ', '.join(f'{fmt(x.get("per_frame_x_real_time"))}x' for x in al.get('runs') or [])
            + f'), whole command {fmt(al.get("whole_command_x_real_time"))}x, 10-minute run '
            f'{fmt(al.get("long_run_x_real_time"))}x.',
        ]
    st = r.get('stage_ms_median') or {}
    lines += [
        '',
        f'Replay loop alone {fmt(r.get("replay_loop_s"))} s '
        f'({fmt(r.get("replay_loop_x_real_time"))}x); '
        f'CPU {fmt(r.get("cpu_s"))} s ({fmt(r.get("cpu_x_real_time"))}x on an idle core). Median '
        'per frame: ' + ', '.join(f'{k} {fmt(v)} ms' for k, v in st.items()) + '.',
    ]
    return lines + ['']


def graph_section(gr) -> list[str]:
    lines, r = section('ROS graph at 10 Hz (issue 5)', gr)
    if r is None:
        return lines
    lines += [
        f'`polarization-compass sim --realtime` at {fmt(r["rate_hz"])} Hz, {r["resolution"]}, '
        f'{r["expected_frames"]} frames ({r["turns"]:g} turn at {r["turn_rate_deg_s"]:g} deg/s). '
        'Sustained rate: '
        "the slowest estimator/corrector node's processed inputs per second (its last 100); "
        'latency: image '
        'published by the simulator to the heading at the evaluator (wall clock).',
        '',
    ]
    rows, detail = [], []
    for run in r['runs']:
        if run.get('status') != 'ok':
            rows.append(
                [run['graph'], run.get('status', '?')[:80], '-', '-', '-', '-', '-', '**FAIL**']
            )
            continue
        sim, ch, lat = run['simulator'], run['checks'], run['least_squares_corrected_latency_ms']
        rows.append(
            [
                run['graph'],
                f'{sim["frames"]}/{run["expected_frames"]} '
                f'({pass_fail(ch["all_frames_published"])})',
                f'{sim["late_frames"]} (target 0: {pass_fail(ch["no_late_frames"])})',
                f'{run["missed_total"]} (target 0: {pass_fail(ch["no_missed_frames"])})',
                f'{fmt(run["sustained_rate_hz"])} Hz, {run.get("slowest_node")} (target 10: '
                f'{pass_fail(ch["sustained_rate"])})',
                fmt(sim.get('publish_rate_hz')),
                f'{fmt(lat["p50"])} / {fmt(lat["p95"])} (target p95 <= {fmt(lat["target_p95"])}: '
                f'{pass_fail(ch["least_squares_latency_p95"])})',
                pass_fail(run['pass']),
            ]
        )
        for name, d in run['streams'].items():
            detail.append(
                [
                    run['graph'],
                    name,
                    d['count'],
                    d['missed'],
                    fmt(d['latency_ms_p50']),
                    fmt(d['latency_ms_p95']),
                    fmt(d['latency_ms_max']),
                ]
            )
    lines += md_table(
        [
            'graph',
            'frames published',
            'late frames',
            'frames missed (all streams)',
            'sustained rate (slowest node)',
            'simulator publish rate (Hz)',
            'least_squares corrected latency p50 / p95 (ms)',
            'pass',
        ],
        rows,
    )
    for run in r['runs']:
        if run.get('status') == 'ok' and run.get('sim_exit_code'):
            lines += [
                '',
                f'Note: {run["graph"]}: `sim` exited {run["sim_exit_code"]} after the run '
                f"({run.get('sim_error', '')[:200]}); the evaluator's report was complete and is "
                'used.',
            ]
    if detail:
        lines += ['', 'Per stream:', '']
        lines += md_table(
            ['graph', 'stream', 'frames', 'missed', 'latency p50 (ms)', 'p95 (ms)', 'max (ms)'],
            detail,
        )
    return lines + ['']


def peers_section(pe) -> list[str]:
    lines, r = section('Peers', pe)
    if r is None:
        return lines
    for peer in ('pyskylumos', 'polanalyser'):
        p = r['peers'].get(peer, {})
        where = (
            f' (Python {p.get("python")} at `{p.get("interpreter")}`)'
            if p.get('interpreter')
            else ''
        )
        lines.append(
            f'- {peer}: '
            f'{p.get("status")}{" " + str(p.get("version")) if p.get("version") else ""}{where}'
        )
    lines.append('')
    if r['ratios']:
        lines += md_table(
            ['comparison', 'peer (ms)', 'ours (ms)', 'peer / ours'],
            [
                [k, fmt(v['peer_ms']), fmt(v['ours_ms']), fmt(v['peer_over_ours'])]
                for k, v in r['ratios'].items()
            ],
        )
        lines += [
            '',
            f'Image size {r["image_size_px"][0]} x {r["image_size_px"][1]}, one thread each. '
            f'{r["note"]}.',
        ]
    return lines + ['']
