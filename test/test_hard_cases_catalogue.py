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
The catalogue docs/hard-cases.md stays true.

Every test it cites exists, every case issue 8 lists has a row, and every open bug it names is a
strict xfail somewhere (and every strict xfail of the hard-case files is named in it).
"""

from pathlib import Path
import re

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / 'docs' / 'hard-cases.md'
TEST_DIR = ROOT / 'test'

ISSUE_8_CASES = [
    'Sun at the zenith',
    'within 0.5 deg of the zenith',
    'exactly on the horizon',
    'just above / just below',
    'Polar day and polar night',
    'at the poles',
    'on the equator',
    'on the date line',
    'Leap days and year boundaries',
    'Solar noon',
    'at the sun and at the anti-sun',
    'looking straight at the sun',
    'Pitch or roll of +-90',
    'Yaw wrap at +-180',
    'AoP wrap at +-90',
    'DoP of 0',
    'All zero, all saturated',
    'All NaN',
    'A single pixel',
    'Odd mosaic dimensions',
    'Wrong dtype or encoding',
    'Quaternions not unit, zero, NaN',
    'IMU stamps older than the image',
    'IMU stamps far in the future',
    'Tilt outside the error map',
    'Corrupt map files',
    'Corrupt bag files',
]


def cited_tests(text):
    """
    Return the (file, test name) pairs cited in the catalogue.

    (file, test name) pairs cited as ``file.py::name`` or, continuing the last file, ``::name``.
    """
    out = []
    for line in text.splitlines():
        if not line.startswith('|'):
            continue
        current = None
        for m in re.finditer(
            r'(test_[a-z0-9_]+\.py)(::([a-z0-9_]+))?|(?<![\w.])::([a-z0-9_]+)', line
        ):
            if m.group(1):
                current = m.group(1)
                if m.group(3):
                    out.append((current, m.group(3)))
            else:
                assert current is not None, line
                out.append((current, m.group(4)))
    return out


def test_every_cited_test_exists():
    text = DOC.read_text()
    cited = cited_tests(text)
    assert len(cited) > 80
    missing = []
    for fname, name in cited:
        f = TEST_DIR / fname
        if not f.is_file() or not re.search(rf'^def {name}\(', f.read_text(), re.M):
            missing.append(f'{fname}::{name}')
    assert not missing, missing


def test_every_file_cited_as_a_whole_exists():
    for fname in re.findall(
        r'(test_[a-z0-9_]+\.py) \((?:all|[a-zA-Z ]+section)\)', DOC.read_text()
    ):
        assert (TEST_DIR / fname).is_file(), fname


def test_every_case_of_issue_8_has_a_row():
    rows = [
        line
        for line in DOC.read_text().splitlines()
        if line.startswith('| ') and '---' not in line
    ]
    first_cells = [r.split('|')[1] for r in rows]
    for case in ISSUE_8_CASES:
        assert any(case.lower() in c.lower() for c in first_cells), case


def test_open_bugs_are_strict_xfails_and_strict_xfails_are_listed():
    text = DOC.read_text()
    n_open = text.count('**Open bug')
    xfail_files = (
        sorted(f for f in TEST_DIR.glob('test_hard_cases_*.py') if f.name != Path(__file__).name)
        + sorted(TEST_DIR.glob('test_properties_*.py'))
        + [TEST_DIR / 'test_cli_bad_input.py']
    )
    reasons = []
    for f in xfail_files:
        src = f.read_text()
        assert 'xfail(strict=False' not in src and 'mark.skip' not in src, f.name
        reasons += [
            m[1] for m in re.findall(r'xfail\(strict=True, reason=\(?\s*(["\'])bug: (.+?)\1', src)
        ]
    assert (n_open == 0) == (not reasons), (
        n_open,
        reasons,
    )  # open-bug rows exactly when strict xfails exist
    # each bug's code location (module.function or module name) is named in the catalogue
    for r in reasons:
        loc = re.match(r'([A-Za-z_]+(?:\.[A-Za-z_]+)?)', r).group(1)
        head = loc.split('.')[-1] if '.' in loc else loc
        assert head in text or loc in text, (loc, r)
