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
ament_flake8 over every Python file, as a ROS package's test/test_flake8.py runs it.

The configuration is ament's own (``ament_flake8/configuration/ament_flake8.ini``: 99 columns,
google import order, single quotes, pydocstyle through flake8-docstrings) plus E203 ignored, which
``ruff format`` (``make format``) does not follow: the ``[flake8]`` section of ``setup.cfg``.
"""

import configparser
import os
import subprocess

import ament_flake8.main
from ament_flake8.main import main_with_errors
from lint_paths import python_paths
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CONFIG = os.path.join(ROOT, 'setup.cfg')
AMENT_CONFIG = os.path.join(
    os.path.dirname(ament_flake8.main.__file__), 'configuration', 'ament_flake8.ini'
)


def flake8_section(path):
    """Return the ``[flake8]`` options of an ini file, code lists as sets."""
    parser = configparser.ConfigParser()
    parser.read(path)
    return {
        key: set(value.split(',')) if key.endswith('ignore') else value
        for key, value in parser['flake8'].items()
    }


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8(monkeypatch):
    monkeypatch.chdir(ROOT)
    rc, errors = main_with_errors(argv=['--config', CONFIG, *python_paths(ROOT)])
    assert rc == 0, 'Found %d code style errors / warnings:\n' % len(errors) + '\n'.join(errors)


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8_applies_ament_rules(tmp_path, monkeypatch):
    """
    A file breaking one rule of each plugin is refused with each rule's code.

    Guards against a silent pass: a missing plugin (quotes, import order, docstrings, builtins)
    or another line length would drop its code from the report.
    """
    bad = tmp_path / 'bad.py'
    lines = [
        '"""Module without a final period"""',
        'import sys',
        'import os',
        '',
        'x = "double quotes"',
        'list = [sys, os]',
        "y = '" + '.' * (100 - 6) + "'",  # 100 columns
        "z = '" + '.' * (99 - 6) + "'",  # 99 columns
        'u = [ sys]',
        'w = z[len(z) - 3 : len(z)]',
    ]
    bad.write_text('\n'.join(lines) + '\n')
    monkeypatch.chdir(tmp_path)
    rc, errors = main_with_errors(argv=['--config', CONFIG, str(bad)])
    codes = {e.split(': ', 1)[1].split()[0] for e in errors if ': ' in e}
    assert rc == 1
    assert {'D400', 'I100', 'Q000', 'A001', 'E501', 'E201'} <= codes, errors
    # E203 alone is not ament's: ruff format writes the slice of line 10 so
    assert 'E203' not in codes, errors
    # the 99-column line (8) passes, the 100-column one (7) does not
    long_lines = [e for e in errors if ' E501 ' in e]
    assert len(long_lines) == 1 and ':7:100:' in long_lines[0], long_lines


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8_config_is_ament_plus_e203():
    """setup.cfg's ``[flake8]`` is ament_flake8's configuration with E203 added, nothing else."""
    ours, ament = flake8_section(CONFIG), flake8_section(AMENT_CONFIG)
    assert ours['extend-ignore'] == ament['extend-ignore'] | {'E203'}
    assert {k: v for k, v in ours.items() if k != 'extend-ignore'} == {
        k: v for k, v in ament.items() if k != 'extend-ignore'
    }


@pytest.mark.flake8
@pytest.mark.linter
def test_ruff_format_output_passes_flake8(tmp_path, monkeypatch):
    """
    Format with ruff as ``make format`` does: flake8 accepts the result, a second run is a no-op.

    The sample has what the two disagree on unless configured: slices with complex bounds (E203),
    double quotes, an over-long call, unsorted imports and a dict() call.
    """
    ruff = pytest.importorskip('ruff')
    exe = ruff.find_ruff_bin()
    config = os.path.join(ROOT, 'ruff.toml')
    src = tmp_path / 'sample.py'
    src.write_text(
        '"""Sample module."""\n'
        'import sys\nimport os\n\n\n'
        'def f(a, i, j):\n'
        '    """Return pieces."""\n'
        '    b = a[i+1:j]\n'
        '    c = a[len(a) - 3:]\n'
        '    d = dict(x="one", y=[os.sep, sys.platform])\n'
        '    return b, c, d, long_function_name(b, c, d, a, i, j, "more", "args", "and", 1, 2, 3, '
        '4, 5, 6, 7)\n'
        '\n\n'
        'def long_function_name(*args):\n'
        '    """Return the arguments."""\n'
        '    return args\n'
    )

    def make_format():
        for step in (['check', '--fix'], ['format']):
            subprocess.run([exe, *step, '--config', config, '--quiet', str(src)], check=True)

    make_format()
    once = src.read_text()
    assert ' : ' in once and "'one'" in once  # ruff's slice spacing and quotes: the test covers it
    make_format()
    assert src.read_text() == once
    monkeypatch.chdir(tmp_path)
    rc, errors = main_with_errors(argv=['--config', CONFIG, str(src)])
    assert rc == 0, errors
