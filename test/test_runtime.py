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

"""The process plumbing of :mod:`polarization_compass.runtime`."""


def test_kernels_run_single_threaded_during_replay_and_settings_come_back():
    """
    Numba and every loaded OpenBLAS run one thread in the context; their counts come back after.

    BLAS is first set to 2 threads (the suite runs with OPENBLAS_NUM_THREADS=1, which alone could
    not tell a restore from a no-op); the counts are read with threadpoolctl's own report and each
    library's ``openblas_get_num_threads`` through ctypes, independently of the code under test.
    """
    import ctypes

    import numba
    from polarization_compass.runtime import single_threaded_kernels
    import scipy.linalg  # noqa: F401 - loads scipy's OpenBLAS beside numpy's
    from threadpoolctl import threadpool_info, threadpool_limits

    def blas_threads():
        """Return (threadpoolctl's count, the library's own) for each loaded OpenBLAS."""
        out = []
        for lib in threadpool_info():
            if lib['internal_api'] == 'openblas':
                so = ctypes.CDLL(lib['filepath'])
                name = next(
                    f'{prefix}_get_num_threads{suffix}'
                    for prefix in ('scipy_openblas', 'openblas')
                    for suffix in ('64_', '')
                    if hasattr(so, f'{prefix}_get_num_threads{suffix}')
                )
                out.append((lib['num_threads'], getattr(so, name)()))
        return out

    before = numba.get_num_threads()
    with threadpool_limits(limits=2, user_api='blas'):
        assert blas_threads() and all(t == (2, 2) for t in blas_threads()), blas_threads()
        with single_threaded_kernels():
            assert numba.get_num_threads() == 1
            assert all(t == (1, 1) for t in blas_threads()), blas_threads()
        assert numba.get_num_threads() == before
        assert all(t == (2, 2) for t in blas_threads()), blas_threads()


def test_kernel_array_is_c_contiguous_read_only_and_copies_only_another_layout():
    """
    Every layout and writeability comes out as one form; a C array is viewed, not copied.

    Independent checks with numpy's own flags and ``np.shares_memory``; the numba type of the
    result (which is what decides a kernel's compiled signature) is read with ``numba.typeof``.
    """
    import numba
    import numpy as np
    from polarization_compass.runtime import kernel_array

    base = np.arange(12, dtype=np.float32).reshape(3, 4)
    ro = base.copy()
    ro.setflags(write=False)
    fortran = np.asfortranarray(base)
    strided = np.arange(24, dtype=np.float32).reshape(3, 8)[:, ::2]
    types = set()
    for a in (base, ro, fortran, strided):
        out = kernel_array(a)
        assert out.flags.c_contiguous and not out.flags.writeable
        np.testing.assert_array_equal(out, a)
        types.add(numba.typeof(out))
    assert len(types) == 1
    assert base.flags.writeable  # the caller's array stays writeable
    assert np.shares_memory(kernel_array(base), base)  # a view: no copy on the hot path
    assert kernel_array(ro) is ro
    assert not np.shares_memory(kernel_array(fortran), fortran)
    idx = kernel_array([1, 2, 3], np.int64)
    assert idx.dtype == np.int64 and not idx.flags.writeable


def test_pixel_views_hand_the_kernels_one_form_of_rays_and_coordinates():
    """
    The full frame, a stride, a region, a pixel list and F-ordered rays give one numba type each.

    The view's rays and pixel coordinates are the kernels' inputs whose layout and writeability
    varied by path (each variant a separate 5-30 s compilation).
    """
    import dataclasses

    import numba
    import numpy as np
    from polarization_compass.estimators._views import select_view, view_segments

    h, w = 12, 16
    y, x = np.mgrid[1 : h + 1, 1 : w + 1].astype(np.float64)
    rays = np.stack([x - 8.0, y - 6.0, np.full_like(x, 10.0)]).reshape(3, -1).astype(np.float32)
    rays /= np.linalg.norm(rays, axis=0)
    rays.setflags(write=False)  # as the camera's cached rays
    x.setflags(write=False)
    y.setflags(write=False)
    obs = dataclasses.make_dataclass(
        'Obs', ['aop_rad', 'dop', 'valid', 'rays_cam', 'x_px', 'y_px', 'intensity']
    )
    full = obs(
        np.zeros((h, w), np.float32),
        np.ones((h, w), np.float32),
        np.ones((h, w), bool),
        rays,
        x,
        y,
        None,
    )
    fl = obs(
        *(np.asarray(a).reshape(-1)[::3] for a in (full.aop_rad, full.dop, full.valid)),
        rays[:, ::3],
        x.reshape(-1)[::3],
        y.reshape(-1)[::3],
        None,
    )
    cases = [
        (full, {'stride': 1}),
        (full, {'stride': 2}),
        (full, {'stride': 1, 'region': (3, 2, 8, 6)}),
        (dataclasses.replace(full, rays_cam=np.asfortranarray(rays)), {'stride': 1}),
        (fl, {'stride': 1}),
    ]
    types = set()
    for o, knobs in cases:
        v = select_view(o, dict({'region': None}, **knobs))
        arrays, _ = view_segments(v, 4)
        types.add(tuple(numba.typeof(a) for a in (v.rays, v.x_px, v.y_px, *arrays[3:6])))
    assert len(types) == 1, types


def test_sky_kernel_compiles_once_for_the_renderer_and_a_direct_call():
    """
    The Rayleigh kernel gets one argument type from the renderer and from a caller's own rays.

    The renderer hands the sky the camera's cached rays (read-only); a caller of
    :meth:`RayleighSky.polarization` (or the ground's mirror rays) hands fresh writeable ones, here
    even F-ordered float64: each form was a separate compilation of the parallel kernel. Both calls
    must give the same bits for the same rays (the conversion is exact).
    """
    import numpy as np
    from polarization_compass import conventions as cv
    from polarization_compass.camera import CameraModel
    from polarization_compass.render import Renderer, SunDirection
    from polarization_compass.scene import Scene
    from polarization_compass.sky import _rayleigh_kernel, RayleighSky

    cam = CameraModel(
        model='fisheye_equidistant',
        width_px=40,
        height_px=36,
        focal_length_mm=1.0,
        pixel_pitch_x_um=60.0,
        pixel_pitch_y_um=60.0,
    )
    r = Renderer(Scene(camera=cam, sky={'model': 'rayleigh', 'dop_max': 0.8}))
    r.render(attitude=cv.CameraAttitude(10.0, 5.0, -3.0), sun=SunDirection(200.0, 55.0))
    rays_ro = np.asarray(r.pixels.rays_cam, np.float32)
    assert not rays_ro.flags.writeable  # the renderer's path: the camera's cached rays
    sun, zen = np.array([0.3, -0.2, 0.9]), np.array([0.0, 0.6, 0.8])
    sun /= np.linalg.norm(sun)
    zen /= np.linalg.norm(zen)
    sky = RayleighSky(0.8)
    mine = np.asfortranarray(rays_ro.astype(np.float64))  # writeable, another layout and dtype
    for a, b in zip(sky.polarization(sun, zen, rays_ro), sky.polarization(sun, zen, mine)):
        np.testing.assert_array_equal(a, b)
    assert len(_rayleigh_kernel.signatures) == 1, _rayleigh_kernel.signatures


def test_stokes_kernel_compiles_once_for_images_and_pixel_lists():
    """:func:`demosaic.aop_dop_from_stokes` of an image and of a flat pixel list: one signature."""
    import numpy as np
    from polarization_compass.demosaic import aop_dop_from_stokes
    from polarization_compass.demosaic_kernels import _stokes_to_aop_kernel

    rng = np.random.default_rng(3)
    s0 = rng.uniform(1.0, 2.0, (6, 8))
    s1, s2 = rng.uniform(-0.5, 0.5, (2, 6, 8))
    img = aop_dop_from_stokes(s0, s1, s2)
    flat = aop_dop_from_stokes(s0.ravel(), s1.ravel(), s2.ravel())
    for a, b in zip(img, flat):
        assert a.shape == (6, 8) and b.shape == (48,)
        np.testing.assert_array_equal(a.ravel(), b)
    # independent: AoP = atan2(S2, -S1) / 2 modulo pi, DoP = hypot(S1, S2) / S0 (float32 rounding)
    assert img[2].all()
    d_aop = np.angle(np.exp(2j * (img[0] - 0.5 * np.arctan2(s2, -s1))))
    np.testing.assert_allclose(d_aop, 0.0, atol=1e-5)
    np.testing.assert_allclose(img[1], np.hypot(s1, s2) / s0, rtol=1e-5)
    assert len(_stokes_to_aop_kernel.signatures) == 1, _stokes_to_aop_kernel.signatures
