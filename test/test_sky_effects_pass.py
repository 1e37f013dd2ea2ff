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
The one-pass render of the sky, its clouds and the lens (polarization_compass.sky_effects).

When the renderer takes it (and when not), what it counts in the instrumentation, and that the
sky inside it is the ideal render's sky bit for bit (unpolarized light keeps the AoP). The values
of the effects are checked against float64 references in test_sky_effects_reference.py.
"""

import numba
import numpy as np
from polarization_compass import conventions as cv
from polarization_compass import instrumentation
from polarization_compass.camera import CameraModel
from polarization_compass.camera_pixels import PixelSelection
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene, Validity
import pytest

FISHEYE = CameraModel(
    model='fisheye_equidistant',
    width_px=400,
    height_px=360,
    focal_length_mm=1.0,
    pixel_pitch_x_um=6.0,
    pixel_pitch_y_um=6.0,
)
SUN = SunDirection(200.0, 55.0)
ATT = cv.CameraAttitude(10.0, 5.0, -3.0)
CLOUDS = {'clouds': {'coverage': 0.5, 'scale_m': 300.0}}
LENS = {'sun': {}, 'flare': {'radius_px': 9}, 'vignetting': {'law': 'cos4'}}
# a region whose width (180) and size (27000) are not multiples of the 16-lane vectors: row ends
# and the end of each thread's share of the frame fall into the loops' scalar remainders
REGION = PixelSelection.rect(150, 40, 180, 150)
BDL = {'model': 'berry_dennis_lee', 'separation_deg': 18.0, 'dop_max': 0.75}


def scene(**kw):
    base = {
        'camera': FISHEYE,
        'sky': {'model': 'rayleigh', 'dop_max': 0.8},
        'validity': Validity(min_dop=0.05, sun_exclusion_deg=3.0),
        'seed': 4,
    }
    return Scene(**{**base, **kw})


def render_counted(sc):
    instrumentation.reset()
    r = Renderer(sc)
    f = r.render(attitude=ATT, sun=SUN)
    return r, f, instrumentation.counts()


def test_undeclared_effects_never_build_the_pass():
    r, f, c = render_counted(scene())
    assert r.sky_effects is None
    assert not [k for k in c if k.startswith(('sky_effects', 'atmosphere', 'optics'))], c
    assert f.intensity is None


@pytest.mark.parametrize(
    'kw, stages',
    [
        ({'atmosphere': CLOUDS}, {'atmosphere.clouds'}),
        ({'optics': LENS}, {'optics.sun', 'optics.flare', 'optics.vignetting'}),
        ({'optics': {'vignetting': {'k': [-0.2]}}}, {'optics.vignetting'}),
        (
            {'atmosphere': CLOUDS, 'optics': LENS, 'pixels': REGION},
            {'atmosphere.clouds', 'optics.sun', 'optics.flare', 'optics.vignetting'},
        ),
        ({'atmosphere': CLOUDS, 'optics': LENS, 'sky': BDL}, {'atmosphere.clouds', 'optics.sun'}),
    ],
)
def test_clouds_and_lens_over_a_block_run_in_one_pass_and_count_their_stages(kw, stages):
    r, f, c = render_counted(scene(**kw))
    assert r.sky_effects is not None
    assert c.get('sky_effects') == 1, c
    assert c.get('sky.' + r.sky.name) == 1, c
    for k in stages:
        assert c.get(k) == 1, (k, c)
    assert not [k for k in c if k.startswith('radiance')], c
    assert f.intensity is not None and np.isfinite(f.intensity).all()
    assert np.isfinite(f.dop).all() and (f.dop >= 0).all() and (f.dop <= 1).all()


@pytest.mark.parametrize(
    'kw',
    [
        {'atmosphere': {**CLOUDS, 'skyline': {'elevation_deg': 5}}},
        {'atmosphere': {**CLOUDS, 'haze': {'turbidity': 3.0}}},
        {'atmosphere': CLOUDS, 'radiance': {'model': 'cie_clear'}},
        {'optics': LENS, 'pixels': PixelSelection.strided(3)},
        {'optics': LENS, 'pixels': PixelSelection.explicit([3, 50, 200], [7, 90, 300])},
    ],
)
def test_scenes_the_pass_does_not_cover_run_stage_by_stage(kw):
    r, f, c = render_counted(scene(**kw))
    assert r.sky_effects is None
    assert 'sky_effects' not in c, c
    assert c.get('sky.rayleigh') == 1, c


@pytest.mark.parametrize('sky', [None, BDL])
@pytest.mark.parametrize('pixels', [PixelSelection.full(), REGION])
def test_the_sky_inside_the_pass_is_the_ideal_sky_bit_for_bit(sky, pixels):
    """
    Lens light is unpolarized and clouds keep the clear-sky AoP: the AoP equals the ideal render's.

    Exactly, at every pixel of the lens-only frame and at every valid pixel under the clouds, also
    at the row ends and frame ends that the loops evaluate in their scalar remainders.
    """
    kw = {'pixels': pixels} if sky is None else {'pixels': pixels, 'sky': sky}
    clear = Renderer(scene(**kw)).render(attitude=ATT, sun=SUN)
    lens = Renderer(scene(optics=LENS, **kw)).render(attitude=ATT, sun=SUN)
    np.testing.assert_array_equal(lens.aop_rad, clear.aop_rad)
    np.testing.assert_array_equal(lens.valid, clear.valid)
    both = Renderer(scene(atmosphere=CLOUDS, optics=LENS, **kw)).render(attitude=ATT, sun=SUN)
    v = both.valid
    assert v.sum() > 0.3 * clear.valid.sum()
    assert not (v & ~clear.valid).any()  # clouds only remove pixels (minimum DoP)
    np.testing.assert_array_equal(both.aop_rad[v], clear.aop_rad[v])
    assert not both.aop_rad[~v].any() and not both.dop[~v].any()


def test_ideal_render_does_not_depend_on_the_thread_count():
    """
    A pixel's AoP and DoP do not depend on which thread or loop part computes it.

    The sky kernels use no reciprocal estimates, so a vectorised body and a scalar remainder give
    the same bits (with fastmath=True they differed by an ulp at a few pixels per thread share).
    """
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip('needs 2 numba threads')
    before = numba.get_num_threads()
    out = []
    try:
        for threads in (1, 2):
            numba.set_num_threads(threads)
            for sky in (None, BDL):
                kw = {'pixels': REGION} if sky is None else {'pixels': REGION, 'sky': sky}
                f = Renderer(scene(**kw)).render(attitude=ATT, sun=SUN)
                out.append((f.aop_rad.copy(), f.dop.copy()))
    finally:
        numba.set_num_threads(before)
    for one, two in zip(out[:2], out[2:]):
        np.testing.assert_array_equal(one[0], two[0])
        np.testing.assert_array_equal(one[1], two[1])
