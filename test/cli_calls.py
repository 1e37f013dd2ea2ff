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
In-process calls of the command line and the check of a refusal (one line, exit 2).

Used by the tests of bad input (test_cli_bad_input) and by those of single commands that check
their refusals (test_errormap).
"""

from polarization_compass.cli import main


def run(argv, capsys):
    """
    Run one in-process CLI call and return (exit status, stdout, stderr).

    (exit status, stdout, stderr) of one in-process CLI call; argparse's SystemExit is an exit
    status.
    """
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def assert_user_error(rc, out, err, *words):
    assert 'Traceback' not in err and 'internal error' not in err, err
    assert rc == 2, (rc, err)
    assert out == ''
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert 'error' in lines[0]
    for w in words:
        assert w.lower() in lines[0].lower(), (w, lines[0])
