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
def _replay_section(rp) -> list[str]:
    lines, r = _section('Offline replay speed (issue 6)', rp)
    if r is None:
        return lines
    tgt = f'>= {r["target_x_real_time"]:g}x'
    lines += [
        f'`{r["record_command"]}` ({r["frames"]} frames, {_f(r.get("bag_mib"))} MiB, recorded in '
        f'{_f(r.get("record_s"))} s), then `{r["replay_command"]}` at its default knobs (the '
        'shipped '
        'error map, figures written).',
        '',
    ]
    rows = [
        [
            f'whole command ({_f(r["bag_duration_s"])} s recording)',
            f'{_f(r["whole_command_s"])} s',
            f'{_f(r["whole_command_x_real_time"])}x',
            tgt,
            _pass(r['pass_whole_command']),
        ],
        [
            f'per frame after start-up (frames {r.get("skipped_frames")}..{r["frames"]})',
            f'{_f(r.get("per_frame_ms"))} ms (median {_f(r.get("per_frame_ms_median"))}, '
            f'p95 {_f(r.get("per_frame_ms_p95"))})',
            f'{_f(r.get("per_frame_x_real_time"))}x',
            tgt,
            _pass(r.get('pass_per_frame')),
        ],
        [
            '10-minute run (extrapolated: overhead + per-frame)',
            f'overhead {_f(r.get("overhead_s"))} s',
            f'{_f(r.get("long_run_x_real_time"))}x',
            tgt,
            _pass(r.get('pass_long_run')),
        ],
    ]
    lines += _table(['measure', 'time', 'x real time', 'target', 'pass'], rows)
    runs = r.get('runs') or []
    if len(runs) > 1:
        lines += [
            '',
            f'The run with the median per-frame time of {len(runs)} replays of the same bag; per '
            'frame in '
            'each: '
            + ', '.join(
                f'{_f(x.get("per_frame_ms"))} ms ({_f(x.get("per_frame_x_real_time"))}x)'
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
            f'replayed interleaved with the runs above: per frame {_f(al.get("per_frame_ms"))} ms '
            f'({_f(al.get("per_frame_x_real_time"))}x; runs: '
            + ', '.join(f'{_f(x.get("per_frame_x_real_time"))}x' for x in al.get('runs') or [])
            + f'), whole command {_f(al.get("whole_command_x_real_time"))}x, 10-minute run '
            f'{_f(al.get("long_run_x_real_time"))}x.',
        ]
    st = r.get('stage_ms_median') or {}
    lines += [
        '',
        f'Replay loop alone {_f(r.get("replay_loop_s"))} s '
        f'({_f(r.get("replay_loop_x_real_time"))}x); '
        f'CPU {_f(r.get("cpu_s"))} s ({_f(r.get("cpu_x_real_time"))}x on an idle core). Median '
        'per frame: ' + ', '.join(f'{k} {_f(v)} ms' for k, v in st.items()) + '.',
    ]
    return lines + ['']


def _graph_section(gr) -> list[str]:
    lines, r = _section('ROS graph at 10 Hz (issue 5)', gr)
    if r is None:
        return lines
    lines += [
        f'`polarization-compass sim --realtime` at {_f(r["rate_hz"])} Hz, {r["resolution"]}, '
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
                f'{sim["frames"]}/{run["expected_frames"]} ({_pass(ch["all_frames_published"])})',
                f'{sim["late_frames"]} (target 0: {_pass(ch["no_late_frames"])})',
                f'{run["missed_total"]} (target 0: {_pass(ch["no_missed_frames"])})',
                f'{_f(run["sustained_rate_hz"])} Hz, {run.get("slowest_node")} (target 10: '
                f'{_pass(ch["sustained_rate"])})',
                _f(sim.get('publish_rate_hz')),
                f'{_f(lat["p50"])} / {_f(lat["p95"])} (target p95 <= {_f(lat["target_p95"])}: '
                f'{_pass(ch["least_squares_latency_p95"])})',
                _pass(run['pass']),
            ]
        )
        for name, d in run['streams'].items():
            detail.append(
                [
                    run['graph'],
                    name,
                    d['count'],
                    d['missed'],
                    _f(d['latency_ms_p50']),
                    _f(d['latency_ms_p95']),
                    _f(d['latency_ms_max']),
                ]
            )
    lines += _table(
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
        lines += _table(
            ['graph', 'stream', 'frames', 'missed', 'latency p50 (ms)', 'p95 (ms)', 'max (ms)'],
            detail,
        )
    return lines + ['']


def _peers_section(pe) -> list[str]:
    lines, r = _section('Peers', pe)
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
        lines += _table(
            ['comparison', 'peer (ms)', 'ours (ms)', 'peer / ours'],
            [
                [k, _f(v['peer_ms']), _f(v['ours_ms']), _f(v['peer_over_ours'])]
                for k, v in r['ratios'].items()
            ],
        )
        lines += [
            '',
            f'Image size {r["image_size_px"][0]} x {r["image_size_px"][1]}, one thread each. '
            f'{r["note"]}.',
        ]
    return lines + ['']
