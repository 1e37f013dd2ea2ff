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

"""The node pipeline latency and estimator speed sections."""

from __future__ import annotations

from .formatting import fmt, md_table, pass_fail, section, windowed


def pipeline_section(pl) -> list[str]:
    lines, r = section('Node pipeline latency', pl)
    if r is None:
        return lines
    rows = [
        [k, fmt(v.get('median_ms')), fmt(v.get('p95_ms'))] for k, v in r.get('stages', {}).items()
    ]
    lines += md_table(['stage', 'ms median', 'ms p95'], rows)
    if r.get('end_to_end'):
        e = r['end_to_end']
        lines += [
            '',
            f'End to end (image published -> heading received, rclpy, loopback): '
            f'{e.get("status")}, median {fmt(e.get("median_ms"))} ms, '
            f'p95 {fmt(e.get("p95_ms"))} ms '
            f'over {e.get("n")} frames.',
        ]
    return lines + ['']


def knobs_label(method: str, knobs: dict) -> str:
    if windowed(method):
        return f'window {knobs.get("window_px")} px'
    st = knobs.get('stride')
    label = 'all superpixels' if st in (None, 1) else f'stride {st}'
    return label + (f', region {knobs["region"]}' if knobs.get('region') else '')


def estimator_speed_section(es) -> list[str]:
    lines, r = section("Estimator speed against issue 3's targets", es)
    if r is None:
        return lines
    cam = r['camera']
    lines += [
        f'From a {cam["width_px"]} x {cam["height_px"]} {r["bit_depth"]}-bit mosaic '
        f'({r["scene"]}), one core, '
        f"{r['repeats']} timed calls per row after a warm-up: the node's front end "
        '(`HeadingFrontEnd`), '
        "superpixel demosaic of the pixels the method reads + estimate, at the estimator's "
        'defaults. '
        '`tilt_aware` is given the known pitch and roll; the paper methods run uncorrected (their '
        'tilted '
        'error is the tilt error). Pass is judged on the median'
        + ('.' if r['targets_apply'] else '; targets apply to the full sensor only (n/a here).'),
        '',
    ]
    rows = []
    for x in r['rows']:
        tt = x['total']
        rows.append(
            [
                x['method'],
                x['attitude'],
                knobs_label(x['method'], x['knobs']),
                x['pixels'],
                fmt(x['demosaic']['median_ms']),
                fmt(tt['median_ms']),
                fmt(tt['p95_ms']),
                f'<= {fmt(x["target_ms"])}' if x.get('target_ms') is not None else '-',
                pass_fail(x['pass_median']),
                pass_fail(x['pass_p95']),
                fmt(x.get('abs_error_max_deg')),
            ]
        )
    lines += md_table(
        [
            'method',
            'attitude',
            'knobs',
            'pixels',
            'demosaic ms',
            'total ms median',
            'total ms p95',
            'target (ms)',
            'pass (median)',
            'pass (p95)',
            'max abs error (deg)',
        ],
        rows,
    )
    if r.get('methods_missing'):
        lines += ['', f'Methods not available: {", ".join(r["methods_missing"])}.']
    return lines + ['']
