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
Paste the generated parameter tables (specs/params.markdown_tables) into README.md and docs/ros.md.

Run after changing a node parameter: ``.venv/bin/python tools/update_param_docs.py``;
test_graphs.py fails until the documents match params.py.
"""

from pathlib import Path

from polarization_compass.specs.params import markdown_tables

ROOT = Path(__file__).resolve().parent.parent
START = '\n#### sky_simulator\n'
LAST_HEADING = '#### heading_estimator knobs'


def update(path: Path) -> bool:
    text = path.read_text()
    i = text.index(START)
    j = text.index(LAST_HEADING, i)
    lines = text[j:].split('\n')
    k = 1
    while k < len(lines) and not lines[k].startswith('|'):
        k += 1
    while k < len(lines) and lines[k].startswith('|'):
        k += 1
    end = j + len('\n'.join(lines[:k])) + 1
    new = text[:i] + markdown_tables() + text[end:]
    if new != text:
        path.write_text(new)
    return new != text


if __name__ == '__main__':
    for doc in ('README.md', 'docs/ros.md'):
        print(doc, 'updated' if update(ROOT / doc) else 'unchanged')
