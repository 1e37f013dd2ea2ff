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
The Apache-2.0 licence header (package.xml's licence) on every Python file.

On a ROS machine ``ament_copyright`` (package.xml's test_depend) checks it, as in ROS packages; it
is not on PyPI, so elsewhere this file's checker of the same rule does (:func:`header_problem`:
after an optional shebang, the first comment block holds ``Copyright <year> <holder>`` and the
Apache-2.0 notice). A new file starts with :data:`HEADER` (docs/contributing.md).
"""

import os
import re

import ament_flake8.main
from lint_paths import python_files, python_paths
import pytest

try:
    from ament_copyright.main import main as ament_copyright_main
except ImportError:  # not on PyPI: only on a ROS installation
    ament_copyright_main = None

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HEADER_LICENSE = """\
Licensed under the Apache License, Version 2.0 (the "License");
you may not use this file except in compliance with the License.
You may obtain a copy of the License at

    http://www.apache.org/licenses/LICENSE-2.0

Unless required by applicable law or agreed to in writing, software
distributed under the License is distributed on an "AS IS" BASIS,
WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
See the License for the specific language governing permissions and
limitations under the License.
"""
# The header every file of the package starts with (the year is the project's first).
HEADER = (
    '\n'.join(
        ('# ' + line if line else '#')
        for line in ['Copyright 2026 polarization_compass developers', '']
        + HEADER_LICENSE.splitlines()
    )
    + '\n'
)
_COPYRIGHT_RE = re.compile(
    r'^\s*copyright(?:\s+\(c\))?\s+(\d{4}(?:-\d{4})?(?:,\s*\d{4}(?:-\d{4})?)*),?\s+(\S.*)$',
    re.IGNORECASE,
)


def _skip_shebang_and_coding(lines):
    i = 0
    while (
        i < len(lines)
        and lines[i].startswith('#')
        and (lines[i].startswith('#!') or 'coding:' in lines[i] or 'coding=' in lines[i])
    ):
        i += 1
    return i


def header_problem(text):
    """
    Say what is wrong with the licence header of a Python source, or None when it is right.

    The rule is ``ament_copyright``'s for a Python file: after an optional shebang / coding line
    and blank lines, the first ``#`` comment block holds a ``Copyright <year> <holder>`` line
    followed by the Apache-2.0 notice (compared with whitespace collapsed). An empty file passes.

    :param text: file content (str)
    :returns: None, or a one-line reason (str)
    """
    if not text.strip():
        return None
    lines = text.splitlines()
    i = _skip_shebang_and_coding(lines)
    while i < len(lines) and not lines[i].strip():
        i += 1
    block = []
    while i < len(lines) and lines[i].startswith('#'):
        block.append(lines[i][2:] if lines[i].startswith('# ') else lines[i][1:])
        i += 1
    if not block:
        return 'could not find copyright notice'
    for k, line in enumerate(block):
        if _COPYRIGHT_RE.match(line):
            rest = ' '.join(' '.join(block[k + 1 :]).split())
            if ' '.join(HEADER_LICENSE.split()) not in rest:
                return 'copyright notice found, but not the Apache-2.0 licence text'
            return None
    return 'could not find copyright notice'


@pytest.mark.copyright
@pytest.mark.linter
def test_copyright(monkeypatch):
    monkeypatch.chdir(ROOT)
    paths = python_paths(ROOT)
    if ament_copyright_main is not None:
        assert ament_copyright_main(argv=paths) == 0, 'Found errors'
    problems = []
    for path in python_files(paths):
        with open(path, encoding='utf-8') as f:
            why = header_problem(f.read())
        if why:
            problems.append(f'{path}: {why}')
    assert not problems, '\n'.join(problems)


@pytest.mark.copyright
@pytest.mark.linter
def test_header_checker_follows_ament_copyright(tmp_path):
    """
    The project's checker accepts what ament_copyright accepts and refuses what it refuses.

    Independent sample: ament_flake8's own source file, whose OSRF Apache-2.0 header ament's
    linters check in their own repository. Refused: no header, a copyright line without the
    licence, and another licence's text.
    """
    with open(ament_flake8.main.__file__, encoding='utf-8') as f:
        osrf = f.read()
    body = '"""Module."""\n\nx = 1\n'
    cases = {
        'osrf.py': (osrf, True),
        'ours.py': (HEADER + '\n' + body, True),
        'script.py': ('#!/usr/bin/env python3\n' + HEADER + '\n' + body, True),
        'years.py': (HEADER.replace(' 2026 ', ' 2024-2026 ') + body, True),
        'none.py': (body, False),
        'no_licence.py': ('# Copyright 2026 polarization_compass developers\n\n' + body, False),
        'mit.py': (
            '# Copyright 2026 someone\n#\n# Permission is hereby granted, free of charge, to any '
            'person obtaining a copy\n# of this software.\n\n' + body,
            False,
        ),
    }
    for name, (text, ok) in cases.items():
        assert (header_problem(text) is None) == ok, name
        (tmp_path / name).write_text(text)
        if ament_copyright_main is not None:
            assert (ament_copyright_main(argv=[str(tmp_path / name)]) == 0) == ok, name


@pytest.mark.copyright
@pytest.mark.linter
def test_this_file_starts_with_the_header():
    """The header written here is the one the package's files carry (this file's own top)."""
    with open(__file__, encoding='utf-8') as f:
        assert f.read().startswith(HEADER)
