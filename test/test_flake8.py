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
google import order, single quotes, pydocstyle through flake8-docstrings); ``make format``
(tools/lint_fix.py) fixes most of what it reports.
"""

import importlib.util
import os

from ament_flake8.main import main_with_errors
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def lint_paths():
    """Return the top-level files and directories that hold Python code (tools/lint_fix.py)."""
    spec = importlib.util.spec_from_file_location(
        'lint_fix', os.path.join(ROOT, 'tools', 'lint_fix.py')
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.python_paths(ROOT)


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8(monkeypatch):
    monkeypatch.chdir(ROOT)
    rc, errors = main_with_errors(argv=lint_paths())
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
    ]
    bad.write_text('\n'.join(lines) + '\n')
    monkeypatch.chdir(tmp_path)
    rc, errors = main_with_errors(argv=[str(bad)])
    codes = {e.split(': ', 1)[1].split()[0] for e in errors if ': ' in e}
    assert rc == 1
    assert {'D400', 'I100', 'Q000', 'A001', 'E501'} <= codes, errors
    # the 99-column line (8) passes, the 100-column one (7) does not
    long_lines = [e for e in errors if ' E501 ' in e]
    assert len(long_lines) == 1 and ':7:100:' in long_lines[0], long_lines
