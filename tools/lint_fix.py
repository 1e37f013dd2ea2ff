#!/usr/bin/env python3
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
Bring every Python file to the style that ament's linters check (``make format``).

The pipeline, in order (each step is idempotent, so is the whole):

1. the licence header (:data:`HEADER`, the Apache-2.0 form ``ament_copyright`` accepts) goes on
   top of every file that has none (below a shebang line);
2. ``ruff check --fix`` with the rules of ``ruff.toml`` (import order, safe autofixes);
3. ``ruff format`` (99 columns, single quotes: ``ruff.toml``);
4. this module's own rewrites, none of which changes the program (each file's ``ast.dump``
   without docstrings is compared before and after; a file that would differ is left alone):
   over-long comment blocks and prose paragraphs of docstrings are rewrapped (code blocks, tables,
   lists with aligned columns and doctests are never touched), the mechanical docstring rules are
   fixed (summary line capitalised and ending with a period, a first sentence that fits on a line
   split from the rest by a blank line), long string literals are split into implicitly
   concatenated pieces, trailing comments that overflow move above their line, and the summaries
   listed in ``tools/lint_summaries.txt`` are put in front of the docstrings they belong to;
5. ``ruff format`` again, then the spaces ruff puts around a slice colon with complex bounds
   (``a[i + 1 : j]``, pycodestyle E203) are removed.

Usage: ``python tools/lint_fix.py [--check] [paths...]`` (default: every Python file of the
package, its tests, benchmarks, tools and launch files). ``--check`` changes nothing and exits 1
when a file would change. ``--summaries-todo`` lists the docstrings whose summary a person must
write (a first sentence longer than a line, no imperative verb), in the form of
``tools/lint_summaries.txt``: fill in the summaries, append them there and run again.
"""

import argparse
import ast
import inspect
import io
import os
import re
import subprocess
import sys
import textwrap
import tokenize

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MAX_COLUMNS = 99
HEADER_HOLDER = 'polarization_compass developers'
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
HEADER_YEAR = 2026
HEADER = (
    '\n'.join(
        ('# ' + line if line else '#')
        for line in [f'Copyright {HEADER_YEAR} {HEADER_HOLDER}', ''] + HEADER_LICENSE.splitlines()
    )
    + '\n'
)
# Directories never linted: build products, caches, virtual environments.
EXCLUDED_DIRS = {'build', 'install', 'log', 'out'}
SUMMARIES_FILE = os.path.join(ROOT, 'tools', 'lint_summaries.txt')


def python_paths(root=ROOT):
    """
    List the top-level entries of ``root`` that hold Python files, sorted.

    Directories starting with ``.`` or ``_`` (``.venv``, caches) and build products
    (:data:`EXCLUDED_DIRS`) are left out, as ament's linters and colcon do.

    :param root: repository root (str)
    :returns: relative paths (list of str), e.g. ``['bench', 'launch', ..., 'setup.py']``
    """
    out = []
    for name in sorted(os.listdir(root)):
        path = os.path.join(root, name)
        if name[0] in '._' or name in EXCLUDED_DIRS:
            continue
        if os.path.isfile(path) and name.endswith('.py'):
            out.append(name)
        elif os.path.isdir(path) and any(python_files([path])):
            out.append(name)
    return out


def python_files(paths):
    """
    Yield the ``.py`` files under ``paths`` (files or directories), skipping ``.``/``_`` dirs.

    :param paths: files or directories (iterable of str)
    :returns: generator of file paths (str)
    """
    for path in paths:
        if os.path.isfile(path):
            if path.endswith('.py'):
                yield path
            continue
        for dirpath, dirnames, filenames in os.walk(path):
            dirnames[:] = sorted(d for d in dirnames if d[0] not in '._')
            for name in sorted(filenames):
                if name.endswith('.py'):
                    yield os.path.join(dirpath, name)


# --------------------------------------------------------------------------------------------
# Licence header
# --------------------------------------------------------------------------------------------
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
            rest = ' '.join(' '.join(block[k + 1:]).split())
            if ' '.join(HEADER_LICENSE.split()) not in rest:
                return 'copyright notice found, but not the Apache-2.0 licence text'
            return None
    return 'could not find copyright notice'


def add_header(text):
    """
    Return ``text`` with :data:`HEADER` inserted when it has no valid header.

    :param text: file content (str)
    :returns: new content (str); unchanged when the header is already right
    """
    if header_problem(text) is None:
        return text
    lines = text.splitlines(keepends=True)
    i = _skip_shebang_and_coding(lines)
    head = ''.join(lines[:i])
    body = ''.join(lines[i:]).lstrip('\n')
    return head + ('\n' if head else '') + HEADER + '\n' + body


# --------------------------------------------------------------------------------------------
# AST guard
# --------------------------------------------------------------------------------------------
def _ast_without_docstrings(text):
    tree = ast.parse(text)
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if (
                body
                and isinstance(body[0], ast.Expr)
                and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)
            ):
                body[0].value.value = '<docstring>'
    return ast.dump(tree)


def same_program(before, after):
    """
    Tell whether two sources parse to the same AST, docstring texts aside.

    :param before: source (str)
    :param after: source (str)
    :returns: bool
    """
    try:
        return _ast_without_docstrings(before) == _ast_without_docstrings(after)
    except SyntaxError:
        return False


# --------------------------------------------------------------------------------------------
# Docstrings
# --------------------------------------------------------------------------------------------
_BULLET_RE = re.compile(r'^([-*+]|\d+[.)]|\(\w\)|[a-z][.)])\s+')
_UNDERLINE_RE = re.compile(r'\s*([-=~^])\1{2,}\s*')
_FIELD_RE = re.compile(r':[\w ]+:(\s|$)')  # a field list item (``:param x:``), not a role
_SENTENCE_END_RE = re.compile(r'[.!?]["\')\]]?$')


def _is_table_line(s):
    """Aligned columns (two or more inner spaces), RST table rules or section underlines."""
    t = s.strip()
    if re.fullmatch(r'[-=~^"+|`#*:. ]{3,}', t):
        return True
    if '|' in t and t.startswith('|'):
        return True
    return bool(re.search(r'\S {2,}\S', t))


def _wrap(words_text, indent, first_indent, width):
    return textwrap.wrap(
        words_text,
        width=width,
        initial_indent=first_indent,
        subsequent_indent=indent,
        break_long_words=False,
        break_on_hyphens=False,
    )


def _rewrap_docstring_lines(lines, closing_len):
    """
    Rewrap the over-long prose paragraphs of a docstring body.

    ``lines`` are the docstring's source lines after the first one (their text includes the
    indentation; the first one starts with the opening quotes). Returns the new lines. Paragraphs
    with a code block, a doctest, a table, a directive or a literal block (after ``::``) are kept
    as they are.
    """
    out = []
    i = 0
    n = len(lines)
    literal_indent = None  # inside a literal block: lines indented more than this are kept
    while i < n:
        # one paragraph: consecutive non-blank lines
        if not lines[i].strip():
            out.append(lines[i])
            i += 1
            continue
        j = i
        while j < n and lines[j].strip():
            j += 1
            if _UNDERLINE_RE.fullmatch(lines[j - 1]):
                break  # a section heading and its underline stand alone
        para = lines[i:j]
        last_para = j == n
        out.extend(_rewrap_paragraph(para, last_para, closing_len, literal_indent))
        first_indent = len(para[0]) - len(para[0].lstrip())
        if literal_indent is not None and first_indent <= literal_indent:
            literal_indent = None
        if para[-1].rstrip().endswith('::') or any(p.lstrip().startswith('.. ') for p in para):
            literal_indent = len(para[-1]) - len(para[-1].lstrip())
        i = j
    return out


def _rewrap_paragraph(para, last_para, closing_len, literal_indent):
    limit = [MAX_COLUMNS] * len(para)
    if last_para:
        limit[-1] = MAX_COLUMNS - closing_len
    if all(len(line) <= lim for line, lim in zip(para, limit)):
        return para
    indents = [len(p) - len(p.lstrip()) for p in para]
    if literal_indent is not None and min(indents) > literal_indent:
        return para
    table = _rewrap_definition_table(para, limit)
    if table is not None:
        return table
    stripped = [p.strip() for p in para]
    if any(
        s.startswith(('>>>', '... ', '.. ', '|', '```', '$ '))
        or _FIELD_RE.match(s)
        or _is_table_line(s)
        for s in stripped
    ):
        return para
    # split into items: a new item starts at a bullet or at a change of indentation that is not
    # the hanging indent of the bullet above
    items = []
    for line, ind, s in zip(para, indents, stripped):
        m = _BULLET_RE.match(s)
        if items:
            it = items[-1]
            if not m and ind == it['cont']:
                it['lines'].append(s)
                it['widths'].append(len(line))
                continue
        items.append(
            {
                'ind': ind,
                'cont': ind + (len(m.group(0)) if m else 0),
                'lines': [s],
                'widths': [len(line)],
            }
        )
    out = []
    for k, it in enumerate(items):
        is_last = last_para and k == len(items) - 1
        lim = MAX_COLUMNS - (closing_len if is_last else 0)
        if all(w <= MAX_COLUMNS for w in it['widths']) and not (
            is_last and it['widths'][-1] > lim
        ):
            out.extend(' ' * it['ind'] + s for s in it['lines'])
            continue
        text = ' '.join(it['lines'])
        wrapped = _wrap(text, ' ' * it['cont'], ' ' * it['ind'], MAX_COLUMNS)
        if is_last and len(wrapped[-1]) > lim:
            # leave room for the closing quotes on the last line
            head = _wrap(text, ' ' * it['cont'], ' ' * it['ind'], lim)
            wrapped = head
        out.extend(wrapped)
    return out


_TERM_RE = re.compile(r'(\s*)(\S(?:.*?\S)?)( {2,})(\S.*)')


def _rewrap_definition_table(para, limit):
    """
    Rewrap the description column of a two-column definition table, or return None.

    Every line is either a term line (``term  description``: a gap of two or more spaces, the
    description starting at one common column) or a continuation of the description at exactly
    that column; the descriptions must be prose (no aligned columns of their own).
    """
    first = _TERM_RE.fullmatch(para[0])
    if not first:
        return None
    col = len(first.group(1)) + len(first.group(2)) + len(first.group(3))
    ind = len(first.group(1))
    items = []
    for line in para:
        m = _TERM_RE.fullmatch(line)
        lead = len(line) - len(line.lstrip())
        if lead == col and not re.search(r'\S {2,}\S', line.strip()):
            if not items or items[-1][0] is None:
                return None
            items[-1][1].append(line.strip())
        elif (
            m
            and len(m.group(1)) == ind
            and len(m.group(1)) + len(m.group(2)) + len(m.group(3)) == col
            and not re.search(r'\S {2,}\S', m.group(4))
        ):
            items.append((m.group(1) + m.group(2) + m.group(3), [m.group(4)]))
        elif lead == ind and len(line) <= MAX_COLUMNS and items:
            items.append((None, [line]))  # a row without the gap (e.g. several terms): as it is
        else:
            return None
    if all(term is None for term, _ in items):
        return None
    out = []
    for k, (term, desc) in enumerate(items):
        if term is None:
            out.extend(desc)
            continue
        lim = limit[-1] if k == len(items) - 1 else MAX_COLUMNS
        wrapped = _wrap(' '.join(desc), ' ' * col, term, MAX_COLUMNS)
        if len(wrapped[-1]) > lim:
            wrapped = _wrap(' '.join(desc), ' ' * col, term, lim)
        out.extend(wrapped)
    # keep the author's breaks unless a line is too long
    return out if any(len(x) > lim for x, lim in zip(para, limit)) else para


def _first_sentence_split(line):
    """Split a summary line at its first sentence end: (sentence, rest) or None."""
    for m in re.finditer(r'(?<=[a-z0-9)\]`\'"])\.(\s+)(?=[A-Z(`\'"])', line):
        before = line[: m.start() + 1]
        # not after an abbreviation such as "e.g." / "i.e." / "eq." / "Fig." / "et al."
        last_word = before.split()[-1].lower() if before.split() else ''
        if last_word in {
            'e.g.',
            'i.e.',
            'eq.',
            'eqs.',
            'fig.',
            'al.',
            'vs.',
            'cf.',
            'no.',
            'sec.',
        }:
            continue
        if before.count('(') != before.count(')') or before.count('`') % 2:
            continue
        return before, line[m.end():]
    return None


def fix_docstring_body(
    body, indent, first_col, closing_len, summaries, quote_text, imperative=False
):
    (
        """
        Apply the docstring rules to one docstring's raw text (between the quotes).

    :param body: raw docstring text (str), first line without indentation
    :param indent: indentation of the continuation lines (str)
    :param first_col: column where the text of the first line starts (int)
    :param closing_len: length of the closing quotes (int, 3)
    :param summaries: see :func:`load_summaries`
    :param quote_text: the opening prefix and quotes, e.g. ``'"""
        '`` or ``'
        r"""'`` (str)
    :returns: new raw text (str)
    """
    )
    lines = body.split('\n')
    # work on the summary-on-the-first-line form; ament's layout is restored at the end
    if len(lines) > 1 and not lines[0].strip() and lines[1].strip():
        lines = [lines[1].strip()] + lines[2:]
    first = lines[0]
    # summary from the table of hand-written ones
    first_para_end = 0
    while first_para_end < len(lines) and lines[first_para_end].strip():
        first_para_end += 1
    para = _normalise(' '.join(lines[:first_para_end]))
    split = _first_sentence_split(para)
    hit = None
    if first_para_end and _summary_key(para) in summaries:
        hit = summaries[_summary_key(para)], ''
    elif first_para_end and split and _summary_key(split[0]) in summaries:
        # the table names the first sentence only: the rest of the paragraph stays
        hit = summaries[_summary_key(split[0])], split[1]
    if hit:
        (summary, replace), rest = hit
        kept = ([indent + rest] if rest else []) if replace else [indent + para]
        tail = lines[first_para_end:]
        if not tail and kept:
            tail = [indent]  # the closing quotes go on a line of their own
        lines = [summary] + ([''] + kept if kept else []) + tail
        first = lines[0]
    # D401: a function's summary starts with the imperative ('Returns' -> 'Return')
    if imperative:
        first = _imperative(first)
    # D210: no whitespace around the text (unless it would then touch a quote)
    if first != first.lstrip() and not first.lstrip().startswith(quote_text[-1]):
        first = first.lstrip()
    if len(lines) == 1 and not first.rstrip().endswith(quote_text[-1]):
        first = first.rstrip()
    # D403: capitalise a lower-case first word
    m = re.match(r'([a-z]+)(\b)', first)
    if m and not re.match(r'[a-z]+[_(.\[\d]', first) and m.group(1) not in {'e', 'i'}:
        first = first[0].upper() + first[1:]
    lines[0] = first
    # D205/D400 for a multi-line first paragraph whose first sentence fits on the first line
    if len(lines) > 1 and lines[1].strip() and not _BULLET_RE.match(lines[1].strip()):
        split = _first_sentence_split(lines[0])
        if split:
            sentence, rest = split
            para_end = 1
            while para_end < len(lines) and lines[para_end].strip():
                para_end += 1
            lines = [sentence, '', indent + rest] + lines[1:]
    # D400: a one-line summary paragraph gets its period
    summary_alone = len(lines) == 1 or not lines[1].strip()
    s = lines[0].rstrip()
    if summary_alone and s and not _SENTENCE_END_RE.search(s) and not s.endswith('::'):
        if s.endswith((':', ';', ',')):
            s = s[:-1]
        room = MAX_COLUMNS - first_col - (closing_len if len(lines) == 1 else 0)
        if len(s) + 1 <= room:
            lines[0] = s + '.' + lines[0][len(lines[0].rstrip()):]
    # ament_pep257 (D213): a multi-line docstring starts on the line after the quotes; one whose
    # continuation lines are all blank becomes a one-line docstring when it fits (D200)
    if len(lines) > 1 and lines[0].strip():
        if not any(ln.strip() for ln in lines[1:]) and (
            first_col + len(lines[0].rstrip()) + closing_len <= MAX_COLUMNS
        ):
            lines = [lines[0].rstrip()]
        else:
            lines = ['', indent + lines[0]] + lines[1:]
    # D209: the closing quotes of a multi-line docstring go on a line of their own
    if len(lines) > 1 and lines[-1].strip():
        lines.append(indent)
    # D407: a ``Returns``/``Raises``/``Yields`` header without its dashed underline, followed by
    # one line of text, becomes a sentence ("Returns (a, b).") instead of a malformed section
    for k in range(1, len(lines) - 1):
        head = lines[k].strip()
        nxt = lines[k + 1].strip()
        if (
            head in ('Returns', 'Return', 'Raises', 'Raise', 'Yields', 'Yield')
            and not lines[k - 1].strip()
            and nxt
            and not _UNDERLINE_RE.fullmatch(lines[k + 1])
            and (k + 2 >= len(lines) or not lines[k + 2].strip())
            and len(lines[k]) + 1 + len(nxt) <= MAX_COLUMNS
        ):
            lines[k:k + 2] = [lines[k].rstrip() + ' ' + nxt]
            break
    # D413: a blank line after the last numpy-style section (``Returns`` + ``-------``)
    if len(lines) > 2 and lines[-2].strip() and any(_UNDERLINE_RE.fullmatch(x) for x in lines[1:]):
        lines.insert(len(lines) - 1, '')
    # rewrap over-long prose; the first line carries the opening quotes, so that it is measured
    # from the right column and wrapped together with the rest of its paragraph
    opening = ' ' * (first_col - len(quote_text)) + quote_text
    body_lines = [opening + lines[0] if lines[0].strip() else ''] + lines[1:]
    new_lines = _rewrap_docstring_lines(body_lines, closing_len)
    if lines[0].strip():
        assert new_lines[0].startswith(opening), (new_lines[0], opening)
        new_lines[0] = new_lines[0][len(opening):]
    else:
        new_lines[0] = lines[0]
    lines = new_lines
    return '\n'.join(lines)


def _imperative(summary):
    """Put the first word of a summary in the imperative mood, as pydocstyle's D401 suggests."""
    try:
        from pydocstyle.wordlists import IMPERATIVE_VERBS, stem
    except ImportError:  # pydocstyle is pinned with the linters; without it, no change
        return summary
    m = re.match(r'([A-Za-z]+)\b', summary)
    if not m:
        return summary
    word = m.group(1).lower()
    forms = IMPERATIVE_VERBS.get(stem(word))
    if not forms or word in forms:
        return summary
    best = max(forms, key=lambda f: len(os.path.commonprefix([word, f])))
    return best.capitalize() + summary[m.end():]


def _normalise(text):
    return ' '.join(text.split())


def _summary_key(text):
    """Normalise a first paragraph for lookup: whitespace, first letter's case, final period."""
    t = _normalise(text).rstrip('.')
    return t[:1].lower() + t[1:]


def load_summaries(path=SUMMARIES_FILE):
    """
    Read the hand-written summary lines of ``tools/lint_summaries.txt``.

    The file holds blocks separated by blank lines; each block is a docstring's old first
    paragraph (any wrapping), a line ``=>`` (the summary goes in front of the old paragraph) or
    ``=>>`` (the summary replaces it), and the new one-line summary. Lines starting with ``#`` are
    comments.

    :param path: file (str)
    :returns: dict (normalised old paragraph -> (summary (str), replace (bool)))
    """
    out = {}
    if not os.path.exists(path):
        return out
    with open(path, encoding='utf-8') as f:
        text = f.read()
    for block in re.split(r'\n\s*\n', text):
        lines = [ln for ln in block.splitlines() if not ln.startswith('#')]
        arrows = [k for k, ln in enumerate(lines) if ln.strip() in ('=>', '=>>')]
        if not arrows:
            continue
        k = arrows[0]
        summary = ' '.join(lines[k + 1:]).strip()
        out[_summary_key(' '.join(lines[:k]))] = (summary, lines[k].strip() == '=>>')
    return out


def _docstring_nodes(tree):
    """Yield (docstring constant node, whether D401 applies to it) for every docstring."""
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if (
                body
                and isinstance(body[0], ast.Expr)
                and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)
            ):
                yield body[0].value, _wants_imperative(node)


def _wants_imperative(node):
    """D401 applies to functions other than tests and properties (pydocstyle's rule)."""
    if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
        return False
    if node.name.startswith('test'):
        return False
    for dec in node.decorator_list:
        name = dec.attr if isinstance(dec, ast.Attribute) else getattr(dec, 'id', '')
        if name in ('property', 'cached_property') or name.endswith(('setter', 'deleter')):
            return False
    return True


def fix_docstrings(text, summaries):
    """
    Apply :func:`fix_docstring_body` to every docstring of a source.

    :param text: source (str)
    :param summaries: see :func:`load_summaries`
    :returns: new source (str)
    """
    tree = ast.parse(text)
    lines = text.splitlines(keepends=True)
    offsets = [0]
    for line in lines:
        offsets.append(offsets[-1] + len(line))
    edits = []
    for node, imperative in _docstring_nodes(tree):
        start = offsets[node.lineno - 1] + _char_col(lines[node.lineno - 1], node.col_offset)
        end = offsets[node.end_lineno - 1] + _char_col(
            lines[node.end_lineno - 1], node.end_col_offset
        )
        src = text[start:end]
        m = re.fullmatch(r'([rR]?)("""|\'\'\')(.*)\2', src, re.DOTALL)
        if not m or '\\\n' in src:
            continue
        prefix, quote, body = m.groups()
        col = _char_col(lines[node.lineno - 1], node.col_offset)
        indent = ' ' * col
        new_body = fix_docstring_body(
            body,
            indent,
            col + len(prefix) + len(quote),
            len(quote),
            summaries,
            prefix + quote,
            imperative,
        )
        if new_body != body:
            edits.append((start, end, prefix + quote + new_body + quote))
    for start, end, new in sorted(edits, reverse=True):
        text = text[:start] + new + text[end:]
    return text


def _char_col(line, byte_col):
    return len(line.encode('utf-8')[:byte_col].decode('utf-8', errors='ignore'))


# --------------------------------------------------------------------------------------------
# Comments
# --------------------------------------------------------------------------------------------
_NOQA_REASON_RE = re.compile(
    r'#\s*noqa:\s*([A-Z]+[0-9]+(?:,\s*[A-Z]+[0-9]+)*)\s*(?:-|:|--)\s+(\S.*)'
)
_PRAGMA_RE = re.compile(r'#\s*(noqa|type:|pragma|fmt:|pylint|nosec)')


def fix_comments(text):
    """
    Rewrap over-long comment blocks and move over-long trailing comments above their line.

    A comment block is a run of lines holding only a comment, at one indentation; a block is
    rewrapped only when one of its lines is too long, and paragraphs inside it (separated by ``#``
    lines), indented lines, bullets and lines with aligned columns keep their breaks.

    :param text: source (str)
    :returns: new source (str)
    """
    lines = text.split('\n')
    comment_lines = set()
    trailing = {}
    try:
        for tok in tokenize.generate_tokens(io.StringIO(text).readline):
            if tok.type == tokenize.COMMENT:
                row, col = tok.start
                if lines[row - 1][:col].strip():
                    trailing[row - 1] = col
                else:
                    comment_lines.add(row - 1)
    except (tokenize.TokenError, IndentationError):
        return text
    out = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if i in trailing and len(line) > MAX_COLUMNS:
            col = trailing[i]
            comment = line[col:]
            noqa = _NOQA_REASON_RE.fullmatch(comment)
            if noqa:
                # ``# noqa: CODE - reason``: the reason goes above, the pragma stays on its line
                code = line[:col].rstrip()
                ind = ' ' * (len(line) - len(line.lstrip()))
                out.extend(_wrap(noqa.group(2), ind + '# ', ind + '# ', MAX_COLUMNS))
                out.append(f'{code}  # noqa: {noqa.group(1)}')
                i += 1
                continue
            if not _PRAGMA_RE.match(comment) and not line.startswith('#!'):
                code = line[:col].rstrip()
                ind = ' ' * (len(line) - len(line.lstrip()))
                body = comment.lstrip('#').strip()
                out.extend(_wrap(body, ind + '# ', ind + '# ', MAX_COLUMNS) or [ind + '#'])
                out.append(code)
                i += 1
                continue
        if i in comment_lines:
            j = i
            ind = len(line) - len(line.lstrip())
            while (
                j < len(lines)
                and j in comment_lines
                and (len(lines[j]) - len(lines[j].lstrip()) == ind)
            ):
                j += 1
            block = lines[i:j]
            if any(len(b) > MAX_COLUMNS for b in block) and not any(
                _PRAGMA_RE.match(b.strip()) or b.startswith('#!') for b in block
            ):
                out.extend(_rewrap_comment_block(block, ind))
            else:
                out.extend(block)
            i = j
            continue
        out.append(line)
        i += 1
    return '\n'.join(out)


def _rewrap_comment_block(block, ind):
    marker = '#:' if all(b.strip().startswith('#:') for b in block) else '#'
    prefix = ' ' * ind + marker + ' '
    texts = [b.strip()[len(marker):] for b in block]  # after '#' or '#:'
    out = []
    para = []

    def flush():
        if para:
            out.extend(_wrap(' '.join(para), prefix, prefix, MAX_COLUMNS))
            para.clear()

    for raw, t in zip(block, texts):
        s = t[1:] if t.startswith(' ') else t
        keep = (
            not s.strip()
            or s.startswith(' ')
            or _BULLET_RE.match(s)
            or _is_table_line(s)
            or not t.startswith(' ')
        )
        if keep:
            flush()
            if _BULLET_RE.match(s) and len(raw) > MAX_COLUMNS:
                m = _BULLET_RE.match(s)
                out.extend(_wrap(s, prefix + ' ' * len(m.group(0)), prefix, MAX_COLUMNS))
            else:
                out.append(raw)
        else:
            para.append(s.strip())
    flush()
    return out


# --------------------------------------------------------------------------------------------
# Long string literals
# --------------------------------------------------------------------------------------------
def fix_long_strings(text):
    """
    Split a one-line string literal that overflows into implicitly concatenated pieces.

    Only plain or f-string literals (no bytes, no raw strings with trailing backslashes) on a line
    of their own or as the last item before a closing bracket are split, at spaces, and only
    inside brackets, so the AST is unchanged (the parser joins adjacent literals).

    :param text: source (str)
    :returns: new source (str)
    """
    lines = text.split('\n')
    try:
        toks = list(tokenize.generate_tokens(io.StringIO(text).readline))
    except (tokenize.TokenError, IndentationError):
        return text
    depth = 0
    strings = []
    for tok in toks:
        if tok.type == tokenize.OP and tok.string in '([{':
            depth += 1
        elif tok.type == tokenize.OP and tok.string in ')]}':
            depth -= 1
        elif tok.type == tokenize.STRING and tok.start[0] == tok.end[0]:
            strings.append((tok, depth))
    edits = {}
    for tok, d in strings:
        row = tok.start[0] - 1
        line = lines[row]
        if len(line) <= MAX_COLUMNS or row in edits:
            continue
        s = tok.string
        m = re.match(r'([a-zA-Z]*)([\'"])', s)
        prefix, q = m.group(1), m.group(2)
        if 'b' in prefix.lower() or s.startswith(prefix + q * 3):
            continue
        col = tok.start[1]
        inner = s[len(prefix) + 1:-1]
        before = line[:col]
        # the piece boundaries must be outside {} fields of an f-string
        after = line[tok.end[1]:]
        width = MAX_COLUMNS - col - len(prefix) - 2 - len(after.rstrip())
        wrap = d == 0
        if wrap:
            # a lone right-hand side (``x = '...'``, ``return '...'``): parenthesised, so that the
            # pieces can go on lines of their own (the parentheses do not change the AST)
            if after.strip() or not re.fullmatch(r'\s*(return|[\w.]+\s*[-+]?=)\s*', line[:col]):
                continue
            col = len(line) - len(line.lstrip()) + 4
            width = MAX_COLUMNS - col - len(prefix) - 2
        pieces = _split_literal(inner, width, 'f' in prefix.lower())
        if pieces is None or len(pieces) < 2:
            continue
        ind = ' ' * col
        new = []
        for k, p in enumerate(pieces):
            pre = prefix
            if 'f' in prefix.lower() and '{' not in p and '}' not in p:
                pre = prefix.replace('f', '').replace('F', '')
            lit = pre + q + p + q
            if k == 0 and not wrap:
                new.append(before + lit)
            else:
                new.append(ind + lit)
        new[-1] += after
        if wrap:
            new = [before + '('] + new + [' ' * (col - 4) + ')']
        if any(len(n) > MAX_COLUMNS for n in new[1:-1]):
            continue
        edits[row] = new
    if not edits:
        return text
    out = []
    for k, line in enumerate(lines):
        out.extend(edits.get(k, [line]))
    return '\n'.join(out)


def _split_literal(inner, width, is_f):
    """Cut the literal's text at spaces into pieces whose literal fits in ``width`` columns."""
    if width < 20:
        return None
    # positions where a cut is allowed: after a space, outside {} fields and escape sequences
    allowed = []
    level = 0
    k = 0
    while k < len(inner):
        c = inner[k]
        if c == '\\':
            k += 2
            continue
        if is_f and c == '{':
            if inner[k:k + 2] == '{{':
                k += 2
                continue
            level += 1
        elif is_f and c == '}':
            if inner[k:k + 2] == '}}' and level == 0:
                k += 2
                continue
            level -= 1
        elif c == ' ' and level == 0:
            allowed.append(k + 1)
        k += 1
    pieces = []
    start = 0
    while len(inner) - start > width:
        cands = [a for a in allowed if start < a <= start + width]
        if not cands:
            return None
        cut = cands[-1]
        pieces.append(inner[start:cut])
        start = cut
    pieces.append(inner[start:])
    return pieces


# --------------------------------------------------------------------------------------------
# Slices (E203)
# --------------------------------------------------------------------------------------------
def fix_slice_spaces(text):
    """
    Remove the spaces ruff puts around a slice colon with complex bounds (``a[i + 1 : j]``).

    pycodestyle's E203 (ament_flake8) rejects the space before such a colon. Only ``:`` tokens
    whose innermost bracket is a subscript ``[`` are touched.

    :param text: source (str)
    :returns: new source (str)
    """
    try:
        toks = list(tokenize.generate_tokens(io.StringIO(text).readline))
    except (tokenize.TokenError, IndentationError):
        return text
    lines = text.split('\n')
    stack = []
    prev = None
    cuts = []  # (row, col_start, col_end) of whitespace to remove
    for k, tok in enumerate(toks):
        if tok.type == tokenize.OP and tok.string in '([{':
            subscript = (
                tok.string == '['
                and prev is not None
                and (
                    prev.type in (tokenize.NAME, tokenize.STRING)
                    and prev.string
                    not in {
                        'in',
                        'return',
                        'and',
                        'or',
                        'not',
                        'yield',
                        'else',
                        'if',
                        'is',
                        'lambda',
                        'await',
                        'assert',
                        'del',
                    }
                    or prev.type == tokenize.OP
                    and prev.string in ')]}'
                )
            )
            stack.append(subscript)
        elif tok.type == tokenize.OP and tok.string in ')]}':
            if stack:
                stack.pop()
        elif tok.type == tokenize.OP and tok.string == ':' and stack and stack[-1]:
            row, col = tok.start
            line = lines[row - 1]
            if (
                col > 0
                and line[col - 1] == ' '
                and prev is not None
                and prev.end[0] == row
                and not (prev.type == tokenize.OP and prev.string in ',[:(')
            ):
                cuts.append((row - 1, prev.end[1], col))
                nxt = toks[k + 1]
                if nxt.start[0] == row and nxt.start[1] > col + 1:
                    cuts.append((row - 1, col + 1, nxt.start[1]))
        if tok.type not in (tokenize.NL, tokenize.NEWLINE, tokenize.COMMENT):
            prev = tok
    for row, a, b in sorted(cuts, reverse=True):
        lines[row] = lines[row][:a] + lines[row][b:]
    return '\n'.join(lines)


# --------------------------------------------------------------------------------------------
# Driver
# --------------------------------------------------------------------------------------------
def own_fixes(text, summaries, slices=True):
    """
    Run this module's rewrites on one source, guarded by the AST comparison.

    :param text: source (str)
    :param summaries: see :func:`load_summaries`
    :param slices: also apply :func:`fix_slice_spaces` (bool)
    :returns: (new source (str), list of step names that were refused (list of str))
    """
    refused = []
    steps = [
        ('docstrings', lambda t: fix_docstrings(t, summaries)),
        ('comments', fix_comments),
        ('strings', fix_long_strings),
    ]
    if slices:
        steps.append(('slices', fix_slice_spaces))
    for name, step in steps:
        new = step(text)
        if new != text:
            if same_program(text, new):
                text = new
            else:
                refused.append(name)
    return text, refused


def _ruff(*args):
    exe = os.path.join(os.path.dirname(sys.executable), 'ruff')
    cmd = [exe if os.path.exists(exe) else 'ruff', *args]
    try:
        return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    except FileNotFoundError:
        sys.exit('lint_fix: ruff is not installed (it is pinned in requirements.txt: make venv)')


def run(paths, check=False):
    """
    Run the whole pipeline on ``paths``; return the files it changed (or would change).

    :param paths: files or directories relative to the repository root (list of str)
    :param check: change nothing, only report (bool)
    :returns: list of changed file paths (list of str)
    """
    files = list(python_files([os.path.join(ROOT, p) for p in paths]))
    before = {f: open(f, encoding='utf-8').read() for f in files}
    if check:
        import shutil
        import tempfile

        tmp = tempfile.mkdtemp(prefix='lint_fix_')
        try:
            for f in files:
                rel = os.path.relpath(f, ROOT)
                os.makedirs(os.path.join(tmp, os.path.dirname(rel)), exist_ok=True)
                shutil.copy(f, os.path.join(tmp, rel))
            shutil.copy(os.path.join(ROOT, 'ruff.toml'), tmp)
            _pipeline(tmp, [os.path.join(tmp, os.path.relpath(f, ROOT)) for f in files])
            changed = [
                f
                for f in files
                if open(os.path.join(tmp, os.path.relpath(f, ROOT)), encoding='utf-8').read()
                != before[f]
            ]
        finally:
            shutil.rmtree(tmp)
        return changed
    _pipeline(ROOT, files)
    return [f for f in files if open(f, encoding='utf-8').read() != before[f]]


def _pipeline(root, files):
    summaries = load_summaries()
    for f in files:
        text = open(f, encoding='utf-8').read()
        new = add_header(text)
        if new != text:
            with open(f, 'w', encoding='utf-8') as h:
                h.write(new)
    cfg = os.path.join(root, 'ruff.toml')
    for args in (['check', '--fix', '--quiet', '--exit-zero'], ['format', '--quiet']):
        r = _ruff(*args, '--config', cfg, *files)
        if r.returncode:
            sys.exit(f'lint_fix: ruff {args[0]} failed:\n{r.stdout}{r.stderr}')
    refusals = {}
    for f in files:
        text = open(f, encoding='utf-8').read()
        new, refused = own_fixes(text, summaries, slices=False)
        if refused:
            refusals[f] = refused
        if new != text:
            with open(f, 'w', encoding='utf-8') as h:
                h.write(new)
    r = _ruff('format', '--quiet', '--config', cfg, *files)
    if r.returncode:
        sys.exit(f'lint_fix: ruff format failed:\n{r.stdout}{r.stderr}')
    for f in files:
        text = open(f, encoding='utf-8').read()
        new, refused = own_fixes(text, summaries, slices=True)
        if refused:
            refusals.setdefault(f, []).extend(refused)
        if new != text:
            with open(f, 'w', encoding='utf-8') as h:
                h.write(new)
    for f, names in sorted(refusals.items()):
        print(
            f'lint_fix: {os.path.relpath(f, root)}: left unchanged by step(s) '
            f'{", ".join(sorted(set(names)))} (the AST would change)',
            file=sys.stderr,
        )


def summaries_todo(paths):
    """
    List the docstrings whose summary needs a person, in ``tools/lint_summaries.txt`` form.

    These are the ones pydocstyle still refuses after :func:`run` (D205/D400/D401/D402/D403: a
    first sentence longer than a line, a summary that is not in the imperative mood); each block
    gets its new summary line after ``=>`` (or ``=>>``) and goes into the summaries file.

    :param paths: files or directories (list of str)
    :returns: text of the blocks (str)
    """
    import pydocstyle

    files = list(python_files([os.path.join(ROOT, p) for p in paths]))
    codes = ['D205', 'D400', 'D401', 'D402', 'D403']
    blocks = {}
    for err in pydocstyle.check(files, select=codes):
        d = err.definition
        doc = ast.literal_eval(d.docstring)
        para = _normalise(inspect.cleandoc(doc).split('\n\n')[0])
        module = os.path.relpath(d.module.name, ROOT)
        name = '<module>' if d.name == d.module.name else d.name
        where = f'{module}:{name}'
        head, found = blocks.get(para, (where, set()))
        found.add(err.code)
        blocks[para] = (head, found)
    out = []
    for para, (where, found) in blocks.items():
        out += [f'# {where} ({", ".join(sorted(found))})', para, '=>', '', '']
    return '\n'.join(out)


def main(argv=None):
    """Command line: ``python tools/lint_fix.py [--check] [paths...]``; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    parser.add_argument('paths', nargs='*', help='files or directories (default: all)')
    parser.add_argument('--check', action='store_true', help='report, change nothing')
    parser.add_argument(
        '--summaries-todo',
        action='store_true',
        help='print the docstrings whose summary needs writing by hand (tools/lint_summaries.txt)',
    )
    args = parser.parse_args(argv)
    paths = args.paths or python_paths()
    if args.summaries_todo:
        print(summaries_todo(paths))
        return 0
    changed = run(paths, check=args.check)
    for f in changed:
        print(('would change ' if args.check else 'changed ') + os.path.relpath(f, ROOT))
    return 1 if (args.check and changed) else 0


if __name__ == '__main__':
    sys.exit(main())
