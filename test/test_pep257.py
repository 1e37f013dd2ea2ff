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

"""ament_pep257 (pydocstyle, ament's ignore list) over every Python file, as in ROS packages."""

import os

from ament_pep257.main import main
from lint_paths import python_paths
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257(monkeypatch):
    monkeypatch.chdir(ROOT)
    rc = main(argv=python_paths(ROOT))
    assert rc == 0, 'Found code style errors / warnings'


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257_applies_ament_rules(tmp_path, monkeypatch, capsys):
    """Ament's layout is enforced: summary on the line after the quotes (D213), a period (D400)."""
    bad = tmp_path / 'bad.py'
    bad.write_text('def f():\n    """Summary on the first line\n\n    More.\n    """\n')
    monkeypatch.chdir(tmp_path)
    assert main(argv=[str(bad)]) == 1
    out = capsys.readouterr()
    report = out.out + out.err
    assert 'D213' in report and 'D400' in report, report
    good = tmp_path / 'good.py'
    good.write_text('def f():\n    """\n    Summary on its own line.\n\n    More.\n    """\n')
    assert main(argv=[str(good)]) == 0
