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
is not on PyPI, so elsewhere the project's checker of the same rule does
(``tools/lint_fix.header_problem``: after an optional shebang, the first comment block holds
``Copyright <year> <holder>`` and the Apache-2.0 notice). ``make format`` adds missing headers.
"""

import importlib.util
import os

import ament_flake8.main
import pytest

try:
    from ament_copyright.main import main as ament_copyright_main
except ImportError:  # not on PyPI: only on a ROS installation
    ament_copyright_main = None

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def lint_fix():
    """Import tools/lint_fix.py (the header, the checker and the list of paths)."""
    spec = importlib.util.spec_from_file_location(
        'lint_fix', os.path.join(ROOT, 'tools', 'lint_fix.py')
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.copyright
@pytest.mark.linter
def test_copyright(monkeypatch):
    lf = lint_fix()
    monkeypatch.chdir(ROOT)
    paths = lf.python_paths(ROOT)
    if ament_copyright_main is not None:
        assert ament_copyright_main(argv=paths) == 0, 'Found errors'
    problems = []
    for path in lf.python_files(paths):
        with open(path, encoding='utf-8') as f:
            why = lf.header_problem(f.read())
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
    lf = lint_fix()
    with open(ament_flake8.main.__file__, encoding='utf-8') as f:
        osrf = f.read()
    body = '"""Module."""\n\nx = 1\n'
    cases = {
        'osrf.py': (osrf, True),
        'ours.py': (lf.HEADER + '\n' + body, True),
        'script.py': ('#!/usr/bin/env python3\n' + lf.HEADER + '\n' + body, True),
        'years.py': (lf.HEADER.replace(' 2026 ', ' 2024-2026 ') + body, True),
        'none.py': (body, False),
        'no_licence.py': ('# Copyright 2026 polarization_compass developers\n\n' + body, False),
        'mit.py': (
            '# Copyright 2026 someone\n#\n# Permission is hereby granted, free of charge, to any '
            'person obtaining a copy\n# of this software.\n\n' + body,
            False,
        ),
    }
    for name, (text, ok) in cases.items():
        assert (lf.header_problem(text) is None) == ok, name
        (tmp_path / name).write_text(text)
        if ament_copyright_main is not None:
            assert (ament_copyright_main(argv=[str(tmp_path / name)]) == 0) == ok, name
    # add_header repairs a file without one and leaves a correct one alone
    fixed = lf.add_header('#!/usr/bin/env python3\n' + body)
    assert fixed.startswith('#!/usr/bin/env python3\n\n# Copyright ')
    assert lf.header_problem(fixed) is None and fixed.endswith(body)
    assert lf.add_header(fixed) == fixed
