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
Maps as labelled arrays (issue 17): xarray, NetCDF 3 and the Zarr store.

The NetCDF 3 export has a scipy-only reader; the Zarr sweep store refuses foreign, corrupt and
other-sweep directories.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip(
    'xarray', reason="the 'sweep' extra (installed by make) is needed for Datasets/Zarr"
)

# after the importorskip / skip above, hence E402 (not at the top) and I100 (after pytest)
from polarization_compass.cli import main  # noqa: E402, I100
from polarization_compass.errormap import ErrorMap, ErrorMapError  # noqa: E402
from polarization_compass.errormap_dataset import DIMS, map_to_dataset  # noqa: E402
from polarization_compass.errormap_io import load_error_map  # noqa: E402
from polarization_compass.errormap_netcdf import export_netcdf, read_netcdf_map  # noqa: E402
from polarization_compass.errormap_store import chunk_checksum, SweepStore  # noqa: E402
from polarization_compass.map_bounds import map_digest  # noqa: E402
from polarization_compass.sweep import run_sweep  # noqa: E402
from polarization_compass.sweep_spec import SweepSpec  # noqa: E402
import xarray as xr  # noqa: E402
import zarr  # noqa: E402


def _map() -> ErrorMap:
    """Return a synthetic map whose every value is a known function of its labels."""
    h, y, p, r = (
        np.array([10.0, 40.0]),
        np.array([-90.0, 0.0, 90.0]),
        np.array([-10.0, 0.0, 10.0, 20.0]),
        np.array([-5.0, 5.0]),
    )
    H, Y, P, R = np.meshgrid(h, y, p, r, indexing='ij')
    err = np.stack([0.01 * H + 0.001 * Y - 0.1 * P + 0.2 * R, -(0.02 * H + 0.5 * R)])
    status = np.zeros(err.shape, dtype=np.int8)
    status[1, :, :, 3, :] = -1
    err[1, :, :, 3, :] = 0.0
    meta = {
        'scene': {'camera': {'model': 'pinhole', 'width_px': 64}, 'sky': {'model': 'rayleigh'}},
        'sampling': {'a': {'knobs': {}}},
        'package_version': '9.9.9',
        'format_version': 1,
    }
    return ErrorMap(err, status, ('least_squares', 'zenith'), h, y, p, r, meta).validate()


def test_the_dataset_is_labelled_in_degrees_with_camera_sky_sampling_and_version():
    m = _map()
    ds = map_to_dataset(m)
    assert ds['error_deg'].dims == DIMS and ds['status'].dims == DIMS
    assert ds['yaw'].attrs['units'] == 'deg' and ds['error_deg'].attrs['units'] == 'deg'
    # a value found by its labels is the formula of those labels
    # (a dim named "method" is selected with a dict: sel(method=...) is xarray's own keyword)
    v = float(
        ds['error_deg'].sel(
            {
                'method': 'least_squares',
                'sun_altitude': 40.0,
                'yaw': -90.0,
                'pitch': 20.0,
                'roll': -5.0,
            }
        )
    )
    assert v == pytest.approx(0.01 * 40 + 0.001 * -90 - 0.1 * 20 + 0.2 * -5, abs=1e-12)
    assert (
        int(
            ds['status'].sel(
                {'method': 'zenith', 'sun_altitude': 10.0, 'yaw': 0.0, 'pitch': 20.0, 'roll': 5.0}
            )
        )
        == -1
    )
    assert json.loads(ds.attrs['camera']) == {'model': 'pinhole', 'width_px': 64}
    assert json.loads(ds.attrs['sky']) == {'model': 'rayleigh'}
    assert json.loads(ds.attrs['sampling']) == {'a': {'knobs': {}}}
    assert ds.attrs['package_version'] == '9.9.9'


def test_netcdf3_export_round_trips_and_reads_with_an_independent_reader(tmp_path):
    m = _map()
    path = export_netcdf(m, tmp_path / 'm.nc')
    assert path.read_bytes()[:4] == b'CDF\x02'  # NetCDF 3, 64-bit offset
    back = load_error_map(path)  # the nodes' loader: scipy only
    np.testing.assert_array_equal(back.error_deg, m.error_deg)
    np.testing.assert_array_equal(back.status, m.status)
    assert back.methods == m.methods and back.meta == m.meta
    for a, b in zip(back.axes(), m.axes()):
        np.testing.assert_array_equal(a, b)
    with xr.open_dataset(path, engine='scipy') as ds:  # xarray's own decoding agrees
        assert list(ds['method'].values) == list(m.methods)
        np.testing.assert_array_equal(ds['error_deg'].values, m.error_deg)


@pytest.mark.parametrize(
    'damage, words',
    [
        (lambda b: b[: len(b) // 2], 'corrupt|truncated'),
        (lambda b: b'CDF\x02' + b'\xff' * 60, 'corrupt|truncated'),
        (lambda b: b'\x89HDF\r\n\x1a\n' + b[8:], 'not an .npz|corrupt'),
    ],
)
def test_a_damaged_netcdf_map_is_refused(tmp_path, damage, words):
    path = export_netcdf(_map(), tmp_path / 'm.nc')
    path.write_bytes(damage(path.read_bytes()))
    with pytest.raises(ErrorMapError, match=words):
        load_error_map(path)


def test_netcdf_values_outside_the_map_ranges_are_refused(tmp_path):
    m = _map()
    ds = map_to_dataset(m)
    ds['error_deg'][0, 0, 0, 0, 0] = 120.0  # not folded to (-90, 90]
    ds.attrs['content_blake2b'] = map_digest(  # intact: written so by a buggy writer
        ds['error_deg'].values, m.status, m.methods, m.axes(), ds.attrs['meta_json']
    )
    ds.to_netcdf(tmp_path / 'bad.nc', engine='scipy', format='NETCDF3_64BIT')
    with pytest.raises(ErrorMapError, match='folded'):
        read_netcdf_map(tmp_path / 'bad.nc')
    ds = map_to_dataset(_map()).transpose('sun_altitude', 'method', 'yaw', 'pitch', 'roll')
    ds.to_netcdf(tmp_path / 'dims.nc', engine='scipy', format='NETCDF3_64BIT')
    with pytest.raises(ErrorMapError, match='dims'):
        read_netcdf_map(tmp_path / 'dims.nc')


def _spec(**kw):
    return SweepSpec(['zenith'], [30.0], [0.0, 90.0], [0.0, 10.0], [0.0], **kw)


def test_a_foreign_zarr_store_is_refused_and_left_alone(tmp_path):
    path = tmp_path / 'theirs.zarr'
    g = zarr.open_group(str(path), mode='w')
    g.create_array('data', shape=(3,), dtype='f8')[:] = [1.0, 2.0, 3.0]
    with pytest.raises(ErrorMapError, match='did not write'):
        SweepStore.open(path, _spec())
    with pytest.raises(ErrorMapError, match='did not write'):
        SweepStore.open(path, _spec(), restart=True)  # never deleted by --restart either
    np.testing.assert_array_equal(zarr.open_group(str(path), mode='r')['data'][:], [1.0, 2.0, 3.0])
    with pytest.raises(ErrorMapError, match='did not write'):
        load_error_map(path)


def test_a_corrupt_store_an_other_sweep_and_a_plain_file_are_refused(tmp_path):
    path = tmp_path / 's.zarr'
    SweepStore.open(path, _spec())
    with pytest.raises(ErrorMapError, match='different sweep'):
        SweepStore.open(path, _spec(full_domain=True))
    (path / 'zarr.json').write_text('{ not json')
    with pytest.raises(ErrorMapError, match='not a readable Zarr store'):
        SweepStore.open(path, _spec())
    (tmp_path / 'f.zarr').write_text('x')
    with pytest.raises(ErrorMapError, match='not a directory'):
        SweepStore.open(tmp_path / 'f.zarr', _spec())


def test_an_unfinished_or_damaged_store_is_not_loaded_as_a_map(tmp_path):
    spec = _spec()
    path = tmp_path / 's.zarr'
    assert run_sweep(spec, out=path, workers=1, progress=False, max_chunks=1) is None
    with pytest.raises(ErrorMapError, match='unfinished'):
        load_error_map(path)
    m = run_sweep(spec, out=path, workers=1, progress=False)
    np.testing.assert_array_equal(load_error_map(path).error_deg, m.error_deg)
    g = zarr.open_group(str(path), mode='r+')
    g['error_deg'][0, 0, 1, 1, 0] = (
        m.error_deg[0, 0, 1, 1, 0] + 1.0
    )  # changed behind the checksum's back
    with pytest.raises(ErrorMapError, match=r'chunk \[0, 1\] does not match its checksum'):
        load_error_map(path)


def test_the_checksum_sees_any_changed_value_and_status():
    e = np.linspace(-3, 3, 24).reshape(2, 3, 4)
    s = np.zeros(e.shape, dtype=np.int8)
    c = chunk_checksum(e, s)
    e2 = e.copy()
    e2[1, 2, 3] = np.nextafter(e2[1, 2, 3], 10)  # one ulp
    s2 = s.copy()
    s2[0, 0, 0] = 1
    assert len({c, chunk_checksum(e2, s), chunk_checksum(e, s2)}) == 3 and c != 0


def test_cli_refuses_a_foreign_store_with_one_line_and_exit_2(tmp_path, capsys):
    path = tmp_path / 'theirs.zarr'
    zarr.open_group(str(path), mode='w').create_array('x', shape=(1,), dtype='i4')
    rc = main(
        [
            'errormap',
            '--methods',
            'zenith',
            '--sun-altitude',
            '30',
            '--yaw',
            '0',
            '--pitch',
            '0',
            '--roll',
            '0',
            '--workers',
            '1',
            '--no-progress',
            '--out',
            str(path),
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and 'did not write' in err[0]
