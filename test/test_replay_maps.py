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
Every documented map format loads in replay and the tilt_corrector; a rejected map is an error.

Issue 24 item 5: a valid ``.zarr`` map was refused as "does not exist" by replay and by the
``tilt_corrector`` (a store is a directory), and a map replay could not use left exit 0 with an
empty corrected stream and no reason. Now the map is loaded and checked when the replay is set
up: unreadable, or correcting none of the selected methods, is a
:class:`~polarization_compass.replay.ReplayError` (exit 2) with the reason.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip('xarray', reason="the 'sweep' extra (installed by make) is needed for Zarr")

from polarization_compass.bag.topic_map import default_topic_map  # noqa: E402, I100
from polarization_compass.correction import TiltCorrector  # noqa: E402
from polarization_compass.errormap_netcdf import export_netcdf  # noqa: E402
from polarization_compass.nodes.tilt_corrector import load_corrector  # noqa: E402
from polarization_compass.replay import (  # noqa: E402
    FramePipeline,
    replay_bag,
    ReplayConfig,
    ReplayError,
)
from polarization_compass.sweep import run_sweep, SweepSpec  # noqa: E402


@pytest.fixture(scope='module')
def maps(tmp_path_factory):
    d = tmp_path_factory.mktemp('maps')
    spec = SweepSpec(
        ['zenith'], [20.0, 30.0], np.arange(-180.0, 180.0, 90.0), [-10.0, 0.0, 10.0], [-5.0, 5.0]
    )
    m = run_sweep(spec, out=d / 'map.zarr', workers=1, progress=False)
    m.save(d / 'map.npz')
    export_netcdf(m, d / 'map.nc')
    return {ext: d / f'map.{ext}' for ext in ('zarr', 'npz', 'nc')}


@pytest.mark.parametrize('ext', ['zarr', 'npz', 'nc'])
def test_every_documented_format_loads_in_replay_and_the_tilt_corrector(maps, ext):
    pipe = FramePipeline(
        ReplayConfig(methods=('zenith',), error_map=str(maps[ext])), default_topic_map()
    )
    assert isinstance(pipe.corrector._get('zenith'), TiltCorrector)
    assert isinstance(load_corrector(str(maps[ext]), 'zenith'), TiltCorrector)


def test_a_map_replay_cannot_use_is_an_error_with_the_reason(maps, tmp_path):
    bad = tmp_path / 'bad.npz'
    bad.write_bytes(b'not a map at all')
    with pytest.raises(ReplayError, match='--error-map'):
        FramePipeline(ReplayConfig(methods=('zenith',), error_map=str(bad)), default_topic_map())
    # checked before the bag is read (this one does not even exist)
    with pytest.raises(ReplayError, match='corrects none of the methods least_squares'):
        replay_bag(
            str(tmp_path / 'no-bag'),
            ReplayConfig(methods=('least_squares',), error_map=str(maps['npz'])),
        )
