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

"""The Python sources the linter tests check: package, tests, benchmark, tools, launch files."""

import os

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# Build products, never linted (colcon's and ament's own exclusions).
EXCLUDED_DIRS = {'build', 'install', 'log', 'out'}


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
