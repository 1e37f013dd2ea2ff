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


"""The section of the photodiode array's checks and mount calibration (issue 28)."""

from __future__ import annotations

from .formatting import fmt, md_table, section


def photodiode_section(pd) -> list[str]:
    lines, r = section('Photodiode arrays: checks and mount calibration (issue 28)', pd)
    if r is None:
        return lines
    lines += [r.get('notes', ''), '']
    rows = [
        [
            method,
            f'{fmt(e["estimate_per_sample_ms"]["median_ms"])} ms',
            f'{fmt(e["wiring_check_s"])} s',
            str(e['samples']),
        ]
        for method, e in r['estimate'].items()
    ]
    lines += md_table(
        [
            'method',
            'per sample (readings checks, side rule, sigma)',
            'wiring check per recording',
            'samples',
        ],
        rows,
    )
    m = r['mount']
    lines += [
        '',
        f'calibrate-mount on the three turns: samples {fmt(m["samples_s"])} s, fit '
        f'{fmt(m["fit_s"])} s; pitch, roll {m["pitch_roll_deg"]} deg +- {m["sigma_deg"]} '
        f'(the simulated mount is off by {m["error_in_sigmas"]} sigma)',
        '',
    ]
    return lines
