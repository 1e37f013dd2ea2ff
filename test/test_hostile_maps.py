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
Hostile Zarr and NetCDF maps are refused before their data are read (issue 24).

A store declaring more than its axes, a chunk that is a FIFO or a symlink to ``/dev/zero``, a
NetCDF map with one changed value, nested ``meta_json``: each is a one-line ``ErrorMapError``,
never a hang, gigabytes or a RecursionError.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal

import numpy as np
import pytest

pytest.importorskip('xarray', reason="the 'sweep' extra (installed by make) is needed")

from polarization_compass.cli import main  # noqa: E402, I100
from polarization_compass.errormap import ErrorMap, ErrorMapError  # noqa: E402
from polarization_compass.errormap_io import load_error_map  # noqa: E402
from polarization_compass.errormap_netcdf import export_netcdf  # noqa: E402
from polarization_compass.errormap_store import SweepStore  # noqa: E402
from polarization_compass.sweep import SweepSpec  # noqa: E402


@contextlib.contextmanager
def deadline(seconds: int):
    """Fail instead of hanging: SIGALRM interrupts a blocking open of a FIFO."""

    def fail(*_):
        raise TimeoutError(f'still blocked after {seconds} s')

    old = signal.signal(signal.SIGALRM, fail)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.fixture
def store(tmp_path):
    """Return a complete sweep store of known content, written without running a sweep."""
    spec = SweepSpec(['zenith'], [30.0], [0.0, 90.0], [0.0, 10.0], [0.0])
    s = SweepStore.open(tmp_path / 's.zarr', spec)
    for ip in range(2):
        err = np.array([[[1.5 * ip], [-2.0]]])
        s.write_chunk(0, ip, err, np.zeros(err.shape, np.int8))
    s.finish({**spec.to_meta(), 'format_version': 1})
    return s.path


def _set_shape(path, name, shape):
    meta_file = path / name / 'zarr.json'
    meta = json.loads(meta_file.read_text())
    meta['shape'] = list(shape)
    meta_file.write_text(json.dumps(meta))


def test_the_fixture_store_reads(store):
    m = load_error_map(store)
    np.testing.assert_array_equal(m.error_deg[0, 0, :, :, 0], [[0.0, 1.5], [-2.0, -2.0]])


def test_a_store_declaring_more_than_its_axes_is_refused(store):
    _set_shape(store, 'error_deg', (1, 1, 20000, 2, 20000))
    with pytest.raises(ErrorMapError, match=r'error_deg declares \(1, 1, 20000, 2, 20000\)'):
        load_error_map(store)


def test_consistent_axes_beyond_the_bound_are_refused_before_reading(store):
    for name, n in (('yaw', 90000), ('roll', 90000)):
        _set_shape(store, name, (n,))
    for name in ('error_deg', 'status'):
        _set_shape(store, name, (1, 1, 90000, 2, 90000))
    with pytest.raises(ErrorMapError, match='cells, more than'):
        load_error_map(store)


@pytest.mark.parametrize('kind', ['fifo', 'dev_zero', 'symlink'])
def test_special_files_in_a_store_are_refused_without_blocking(store, tmp_path, kind):
    chunks = (store / 'error_deg').rglob('*')
    victim = sorted(p for p in chunks if p.is_file() and p.name != 'zarr.json')[0]
    victim.unlink()
    if kind == 'fifo':
        os.mkfifo(victim)
    else:
        target = '/dev/zero' if kind == 'dev_zero' else tmp_path / 'elsewhere'
        if kind == 'symlink':
            target.write_bytes(b'')
        os.symlink(target, victim)
    with deadline(30), pytest.raises(ErrorMapError, match='not a regular file'):
        load_error_map(store)
    with deadline(30), pytest.raises(ErrorMapError, match='not a regular file'):
        SweepStore.open(store, SweepSpec(['zenith'], [30.0], [0.0, 90.0], [0.0, 10.0], [0.0]))


def test_nested_meta_json_is_a_user_error(store, capsys):
    import zarr

    g = zarr.open_group(str(store), mode='r+')
    g.attrs['meta_json'] = '[' * 100000 + ']' * 100000
    with pytest.raises(ErrorMapError, match='nested too deeply'):
        load_error_map(store)
    code = main(['allowable-tilt', '--map', str(store), '--max-error', '5'])
    assert code == 2 and 'nested' in capsys.readouterr().err


def _map() -> ErrorMap:
    err = np.linspace(-5.0, 5.0, 8).reshape(1, 2, 2, 2, 1)
    axes = ([20.0, 40.0], [0.0, 90.0], [0.0, 10.0], [0.0])
    meta = {'format_version': 1, 'scene': {}}
    return ErrorMap(err, np.zeros(err.shape, np.int8), ('zenith',), *map(np.array, axes), meta)


def _patch(path, old: bytes, new: bytes):
    data = path.read_bytes()
    assert data.count(old) == 1
    path.write_bytes(data.replace(old, new))


def test_a_changed_netcdf_value_is_refused(tmp_path):
    m = _map()
    p = export_netcdf(m, tmp_path / 'm.nc')
    np.testing.assert_array_equal(load_error_map(p).error_deg, m.error_deg)
    one = np.array([m.error_deg.reshape(-1)[3]], '>f8').tobytes()
    _patch(p, one, np.array([1.25], '>f8').tobytes())  # a valid, folded value
    with pytest.raises(ErrorMapError, match='does not match its digest'):
        load_error_map(p)


def test_a_netcdf_map_without_its_digest_is_refused(tmp_path):
    p = export_netcdf(_map(), tmp_path / 'm.nc')
    _patch(p, b'content_blake2b', b'content_blake2X')
    with pytest.raises(ErrorMapError, match='no content_blake2b'):
        load_error_map(p)


def test_nested_netcdf_meta_json_is_a_user_error(tmp_path):
    from polarization_compass.errormap_dataset import map_to_dataset
    from polarization_compass.map_bounds import map_digest

    m = _map()
    ds = map_to_dataset(m)
    deep = '[' * 100000 + ']' * 100000
    ds.attrs['meta_json'] = deep
    ds.attrs['content_blake2b'] = map_digest(m.error_deg, m.status, m.methods, m.axes(), deep)
    ds.to_netcdf(tmp_path / 'deep.nc', engine='scipy', format='NETCDF3_64BIT')
    with pytest.raises(ErrorMapError, match='nested too deeply'):
        load_error_map(tmp_path / 'deep.nc')


def test_a_stored_chunk_with_an_unknown_status_is_named_and_recomputed(tmp_path, capsys):
    from polarization_compass.sweep import run_sweep

    spec = SweepSpec(['zenith'], [30.0], [0.0, 90.0], [0.0, 10.0], [0.0])
    path = tmp_path / 's.zarr'
    assert run_sweep(spec, out=path, workers=1, progress=False, max_chunks=1) is None
    store = SweepStore.open(path, spec)
    done = [(0, ip) for ip in range(2) if store.read_chunk(0, ip) is not None]
    assert len(done) == 1
    ia, ip = done[0]
    err, status = store.read_chunk(ia, ip)
    bad = status.copy()
    bad[0, 0, 0] = 99  # with a matching checksum: written so, not damaged on disk
    store.write_chunk(ia, ip, err, bad)
    capsys.readouterr()
    m = run_sweep(spec, out=path, workers=1, progress=False)
    log = capsys.readouterr().err
    assert f'{path}: chunk (sun altitude 30 deg, pitch {spec.pitch_deg[ip]:g} deg)' in log
    assert 'unknown code(s) [99]' in log and '--restart' in log
    np.testing.assert_array_equal(m.status[:, ia, :, ip, :], status)
    np.testing.assert_array_equal(load_error_map(path).status, m.status)
