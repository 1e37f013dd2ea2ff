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
The command line's one-line promise at its boundary (issue 24).

What an input causes (RecursionError, MemoryError, cv2.error) is a user error (exit 2), not an
internal one (exit 70); Python warnings are one line without source paths; SIGTERM ends a command
with one line as SIGINT does, after unwinding it (``record-sim`` leaves a bag with its metadata).
"""

import os
from pathlib import Path
import signal
import subprocess
import sys
import time
import warnings

import cv2
import numpy as np
from polarization_compass.cli import cmd_sun, main
import pytest

REPO = Path(__file__).resolve().parents[1]


def _raise(exc):
    def run(args):
        raise exc

    return run


@pytest.mark.parametrize(
    'exc, words',
    [
        (RecursionError('maximum recursion depth exceeded'), 'nested too deeply'),
        (MemoryError(), 'not enough memory'),
        (cv2.error('OpenCV(5.0) decoder: -215:Assertion failed'), 'OpenCV cannot process'),
    ],
    ids=['recursion', 'memory', 'cv2'],
)
def test_what_an_input_causes_is_a_user_error(monkeypatch, capsys, exc, words):
    monkeypatch.setattr(cmd_sun, 'run', _raise(exc))
    code = main(['sun', '--lat', '0', '--lon', '0', '--time', '2026-06-01T12:00:00Z'])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count('\n') == 1 and words in err and 'internal error' not in err


def test_an_unexpected_error_is_still_internal(monkeypatch, capsys):
    monkeypatch.setattr(cmd_sun, 'run', _raise(ZeroDivisionError('x')))
    assert main(['sun', '--lat', '0', '--lon', '0', '--time', '2026-06-01T12:00:00Z']) == 70
    assert 'internal error: ZeroDivisionError' in capsys.readouterr().err


def test_warnings_are_one_line_each_without_source_paths(monkeypatch, capsys):
    def noisy(args):
        warnings.simplefilter('always')  # as outside pytest, where warnings are not errors
        with np.errstate(all='warn'):
            for _ in range(3):
                np.log(np.zeros(2))
        return 0

    monkeypatch.setattr(cmd_sun, 'run', noisy)
    with warnings.catch_warnings():
        assert main(['sun', '--lat', '0', '--lon', '0', '--time', '2026-06-01T12:00:00Z']) == 0
    err = capsys.readouterr().err
    assert err == (
        'polarization-compass sun: warning: RuntimeWarning: divide by zero encountered in log\n'
    )


@pytest.mark.slow
def test_sigterm_ends_record_sim_with_one_line_and_its_metadata(tmp_path):
    bag = tmp_path / 'bag'
    env = {**os.environ, 'PYTHONPATH': f'{REPO}{os.pathsep}{os.environ.get("PYTHONPATH", "")}'}
    argv = ['record-sim', '--duration', '600', '--rate', '1', '--out', str(bag)]
    proc = subprocess.Popen(
        [sys.executable, '-m', 'polarization_compass.cli', *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        t0 = time.monotonic()
        while not (bag / 'bag.mcap').exists() and time.monotonic() - t0 < 120:
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.2)
        time.sleep(1.0)
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 143, err
    assert err == 'polarization-compass record-sim: terminated\n'
    assert 'storage_identifier: mcap' in (bag / 'metadata.yaml').read_text()
