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

"""The rewrites of ``make format`` (tools/lint_fix.py) keep the program and are idempotent."""

import ast
import importlib.util
import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LONG = 'word ' * 30
FILL = 'on and on ' * 3  # pushes a line past 99 columns

SOURCE = f'''
def f(values, first, count):
    """Returns the values from first on, a summary line that is far too long {FILL}to fit.

    A prose paragraph that runs on and on: {LONG}and ends here.

    A literal block follows::

        x = values[first + 1 : first + count]   # a code line that must stay as it is, {FILL}

    ``term``    a definition column whose text is long enough to need wrapping: {LONG}end.
    """
    # a comment block that is too long: {LONG}and ends with a full stop.
    # A second line of the same block.
    message = f'the value {{values[first]!r}} at index {{first}} is refused {FILL}as documented'
    return values[first + 1 : first + count], message  # a trailing comment that overflows {FILL}
'''


def lint_fix():
    """Import tools/lint_fix.py."""
    spec = importlib.util.spec_from_file_location(
        'lint_fix', os.path.join(ROOT, 'tools', 'lint_fix.py')
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.linter
def test_own_fixes_keep_the_program_and_are_idempotent():
    lf = lint_fix()
    new, refused = lf.own_fixes(SOURCE, {})
    assert refused == []
    assert lf.same_program(SOURCE, new)
    # independent check of the same property: equal ASTs once the docstring is set aside
    old_tree, new_tree = ast.parse(SOURCE), ast.parse(new)
    old_doc = ast.get_docstring(old_tree.body[0])
    new_doc = ast.get_docstring(new_tree.body[0])
    old_tree.body[0].body.pop(0)
    new_tree.body[0].body.pop(0)
    assert ast.dump(old_tree) == ast.dump(new_tree)
    assert lf.own_fixes(new, {}) == (new, [])
    lines = new.splitlines()
    code_line = '        x = values[first + 1 : first + count]   # a code line that must stay'
    assert any(line.startswith(code_line) for line in lines), 'the literal block was touched'
    too_long = [ln for ln in lines if len(ln) > 99 and not ln.startswith(code_line)]
    assert too_long == []
    # the docstring keeps its words, in order; only the layout and the summary's verb change
    assert new_doc.split()[0] == 'Return'
    assert old_doc.split()[1:] == new_doc.split()[1:]
    assert '    """\n    Return the values' in new  # ament's layout: summary on the second line
    assert 'return values[first + 1:first + count], message' in new


@pytest.mark.linter
def test_summary_table_puts_a_written_summary_in_front():
    lf = lint_fix()
    src = (
        'def g():\n    """The angle of the thing, which is a long sentence going\n    on '
        'here."""\n'
    )
    table = {
        lf._summary_key('The angle of the thing, which is a long sentence going on here'): (
            'Return the angle of the thing.',
            False,
        )
    }
    new, _ = lf.own_fixes(src, table)
    assert ast.get_docstring(ast.parse(new).body[0]) == (
        'Return the angle of the thing.\n\n'
        'The angle of the thing, which is a long sentence going on here.'
    )
    assert lf.own_fixes(new, table)[0] == new
