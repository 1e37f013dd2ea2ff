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
Photodiode-array recordings are bounded by what their headers declare (issue 24).

An ``.npz`` whose header states 100000 units was decompressed (4.3 GB from 2 MB) before being
refused; the CSV reader refused a valid 2 MB recording (a 1 MiB cap against the documented 1e6
samples). Now the npz is refused from its header and the CSV bound is rows x columns.
"""

import io
import zipfile

import numpy as np
from polarization_compass.photodiode.readings import (
    ArrayRecordingError,
    load_array_recording,
    MAX_SAMPLES,
)
import pytest


def npz_declaring(path, shape, dtype='<f8'):
    """Write an .npz whose 'intensities' header declares ``shape`` but holds no data."""
    head = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        head, {'descr': dtype, 'fortran_order': False, 'shape': shape}
    )
    with zipfile.ZipFile(path, 'w', zipfile.ZIP_DEFLATED) as z:
        z.writestr('intensities.npy', b'\x93NUMPY\x01\x00' + head.getvalue()[8:])


@pytest.mark.parametrize(
    'shape', [(1000, 100000, 2), (MAX_SAMPLES + 1, 4, 2), (10, 4, 9), (10, 8)]
)
def test_an_npz_declaring_too_much_is_refused_before_reading(tmp_path, monkeypatch, shape):
    p = tmp_path / 'r.npz'
    npz_declaring(p, shape)

    def boom(*args, **kwargs):
        raise AssertionError('an array was read before its header was checked')

    monkeypatch.setattr(np.lib.format, 'read_array', boom)
    with pytest.raises(ArrayRecordingError, match='refused before reading'):
        load_array_recording(p)


def test_a_csv_of_more_than_a_mebibyte_is_read(tmp_path):
    rng = np.random.default_rng(1)
    a = rng.random((150_000, 2, 2)) * 1000
    p = tmp_path / 'r.csv'
    with open(p, 'w') as fh:
        fh.write('u0_c0,u0_c1,u1_c0,u1_c1\n')
        np.savetxt(fh, a.reshape(len(a), 4), delimiter=',', fmt='%.17g')
    assert p.stat().st_size > 4 << 20
    got = load_array_recording(p)
    np.testing.assert_array_equal(got.intensities, a)
    assert got.t_offset_s is None


def test_a_csv_larger_than_its_columns_allow_is_refused_unread(tmp_path):
    p = tmp_path / 'r.csv'
    with open(p, 'w') as fh:
        fh.write('u0_c0,u0_c1\n1,2\n')
        fh.truncate(200 << 20)  # sparse: 200 MB of NUL bytes, more than 1e6 rows of 2 fields
    with pytest.raises(ArrayRecordingError, match='refused before reading'):
        load_array_recording(p)


def test_a_csv_line_longer_than_its_columns_allow_is_refused(tmp_path):
    p = tmp_path / 'r.csv'
    p.write_text('u0_c0,u0_c1\n' + ','.join(['1'] * 5000) + '\n')
    with pytest.raises(ArrayRecordingError, match='a line longer than'):
        load_array_recording(p)


def test_a_long_recording_reports_progress_and_the_same_headings():
    from polarization_compass.photodiode.geometry import geometry_from_dict
    from polarization_compass.photodiode.heading import estimate_recording, make_array_estimator
    from polarization_compass.photodiode.simulate import simulate_readings

    unit = {'elevation_deg': 45, 'channels_deg': [135, 45, 90, 0], 'acceptance_deg': 30}
    units = [{'azimuth_deg': a, **unit} for a in (0, 90, 180, 270, 45, 135, 225, 315)]
    g = geometry_from_dict({'angle_zero': 'horizontal', 'angle_sense': 'ccw', 'units': units})
    # 2500 samples: 250 simulated bearings ten times over (simulating is most of the cost; a
    # result out of place by one sample would still differ)
    x = np.concatenate([simulate_readings(g, 210.0, 35.0, np.linspace(0.0, 359.0, 250))] * 10)
    assert x.shape[0] == 2500
    est = make_array_estimator('least_squares', g)
    seen = []
    res = estimate_recording(
        est, x, 210.0, 35.0, 0.0, 0.0, progress=lambda k, n: seen.append((k, n))
    )
    assert seen == [(1000, 2500), (2000, 2500), (2500, 2500)]
    plain = estimate_recording(est, x, 210.0, 35.0, 0.0, 0.0)
    assert [(r.status, r.bearing_deg) for r in res] == [(r.status, r.bearing_deg) for r in plain]
