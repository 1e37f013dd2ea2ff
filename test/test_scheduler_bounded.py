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
``errormap --scheduler`` fails in bounded time with one line on anything but a working scheduler.

Issue 24: a listener that never answers hung, a scheduler without workers waited forever, and
``ucx://``, ``inproc://`` or a service that is not Dask ended in exit 70 and a traceback after
44 s.
"""

import re
import socket
import threading
import time

import pytest

pytest.importorskip('distributed', reason="the 'sweep' extra (installed by make) is needed")

from polarization_compass import sweep_dask  # noqa: E402, I100
from polarization_compass.cli import main  # noqa: E402
from polarization_compass.errormap import ErrorMapError  # noqa: E402

TIMEOUT_S = 2.0


@pytest.fixture
def short_timeout(monkeypatch):
    monkeypatch.setattr(sweep_dask, 'SCHEDULER_TIMEOUT_S', TIMEOUT_S)


@pytest.fixture
def listener():
    """Return a factory of TCP listeners on 127.0.0.1 that never answer or answer as HTTP."""
    sockets = []

    def make(http: bool) -> str:
        srv = socket.socket()
        srv.bind(('127.0.0.1', 0))
        srv.listen(4)
        sockets.append(srv)

        def serve():
            while True:
                try:
                    conn, _ = srv.accept()
                except OSError:
                    return
                sockets.append(conn)
                if http:
                    conn.recv(64)
                    conn.sendall(b'HTTP/1.0 400 Bad Request\r\n\r\nno\n')

        threading.Thread(target=serve, daemon=True).start()
        return f'tcp://127.0.0.1:{srv.getsockname()[1]}'

    yield make
    for s in sockets:
        s.close()


@pytest.mark.parametrize('http', [False, True], ids=['silent', 'http'])
def test_a_listener_that_is_not_a_scheduler_fails_in_bounded_time(short_timeout, listener, http):
    address = listener(http)
    t0 = time.monotonic()
    words = 'answers, but not as' if http else 'does not answer as'
    with pytest.raises(ErrorMapError, match=f'{re.escape(address)} {words} a Dask scheduler'):
        sweep_dask.start(address, None)
    assert time.monotonic() - t0 < 4 * TIMEOUT_S + 5


def test_a_scheduler_without_workers_is_refused(short_timeout):
    import distributed

    with distributed.LocalCluster(
        n_workers=0, processes=False, dashboard_address=None, protocol='tcp://'
    ) as cluster:
        t0 = time.monotonic()
        with pytest.raises(ErrorMapError, match='has no worker'):
            sweep_dask.start(cluster.scheduler_address, None)
        assert time.monotonic() - t0 < 4 * TIMEOUT_S + 5


ERRORMAP = ['errormap', '--sun-altitude', '30:30:1', '--yaw', '0:0:1', '--pitch', '0:0:1']


@pytest.mark.parametrize('address', ['ucx://127.0.0.1:8786', 'inproc://127.0.0.1/1/1', 'silent'])
def test_cli_scheduler_errors_are_one_line_exit_2(
    short_timeout, listener, tmp_path, capsys, address
):
    if address == 'silent':
        address = listener(False)
    argv = ERRORMAP + ['--roll', '0:0:1', '--out', str(tmp_path / 'm.npz'), '--scheduler', address]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count('\n') == 1 and address in err
