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
Test-wide settings: strict numpy, deterministic hypothesis, loopback-only ROS.

Numpy floating-point errors raise, hypothesis is deterministic and bounded, and every ROS process
stays on loopback with a domain id of its own.

ROS domain ids come from one pool, ``POLARIZATION_COMPASS_TEST_DOMAINS`` (default ``1-100``:
below 101 Fast DDS's ports stay under Linux's ephemeral range; e.g. ``118-140`` or
``1-50,200-230``), less the caller's ``ROS_DOMAIN_ID``. Under pytest-xdist each worker takes its
own slice of the pool: the first id of the slice becomes the worker's ``ROS_DOMAIN_ID``
(in-process nodes, the ``ctx`` fixture), and :func:`next_ros_domain` (the ``ros_env`` and
``ros_domain`` fixtures) hands out the others in turn, starting at a place drawn from the process
id, so that two tests of one run never share a domain at the same time, and two runs on one
machine seldom do (give each its own pool).
"""

import os
import random
import re
import subprocess
import sys

from hypothesis import HealthCheck, settings
import numpy as np
import pytest

# Every warning is already an error (pytest.ini); make numpy raise even where warnings are
# filtered.
np.seterr(all='raise', under='ignore')

settings.register_profile(
    'ci',
    max_examples=60,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile('thorough', max_examples=1000, deadline=None)
settings.load_profile(os.environ.get('HYPOTHESIS_PROFILE', 'ci'))

DOMAINS_VARIABLE = 'POLARIZATION_COMPASS_TEST_DOMAINS'


def parse_domains(text: str) -> list[int]:
    """
    Return the ROS domain ids of a pool written as ``'1-100'`` or ``'118-140,200,210-215'``.

    Parameters
    ----------
    text : str
        Comma-separated ids and inclusive ranges ``lo-hi``, each within 0-232 (Fast DDS's limit).

    Returns
    -------
    list of int
        The ids in the order written, without repeats.

    """
    out = []
    for part in text.split(','):
        m = re.fullmatch(r'\s*(\d+)\s*(?:-\s*(\d+)\s*)?', part)
        if m is None:
            raise pytest.UsageError(f'{DOMAINS_VARIABLE}={text!r}: {part!r} is not N or N-M')
        lo, hi = int(m.group(1)), int(m.group(2) or m.group(1))
        if not 0 <= lo <= hi <= 232:
            raise pytest.UsageError(f'{DOMAINS_VARIABLE}={text!r}: {part!r} is not within 0-232')
        out += [d for d in range(lo, hi + 1) if d not in out]
    return out


def worker_domains(pool: list[int], worker: str, count: int) -> list[int]:
    """
    Return the slice of ``pool`` that belongs to pytest-xdist worker ``worker`` of ``count``.

    Parameters
    ----------
    pool : list of int
        Every domain id this run may use.
    worker : str
        ``PYTEST_XDIST_WORKER`` (``'gw0'``, ``'gw1'``, ...); ``''`` without xdist (the whole pool).
    count : int
        ``PYTEST_XDIST_WORKER_COUNT`` (1 without xdist).

    Returns
    -------
    list of int
        At least two ids, disjoint from every other worker's slice.

    """
    index = int(worker[2:]) if worker.startswith('gw') else 0
    size = len(pool) // count
    if size < 2:
        raise pytest.UsageError(
            f'{len(pool)} ROS domain ids ({DOMAINS_VARIABLE}) for {count} pytest workers: each '
            'needs two at least (one for its in-process nodes, one for each test graph)'
        )
    return pool[index * size : (index + 1) * size]


_CALLER_DOMAIN = os.environ.get('ROS_DOMAIN_ID')
_POOL = [
    d for d in parse_domains(os.environ.get(DOMAINS_VARIABLE, '1-100')) if str(d) != _CALLER_DOMAIN
]
_MINE = worker_domains(
    _POOL,
    os.environ.get('PYTEST_XDIST_WORKER', ''),
    int(os.environ.get('PYTEST_XDIST_WORKER_COUNT', '1')),
)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
if 'PYTEST_XDIST_WORKER' in os.environ or _CALLER_DOMAIN is None:
    # every worker inherits the run's ROS_DOMAIN_ID (the Makefile's 73): each takes its own instead
    os.environ['ROS_DOMAIN_ID'] = str(_MINE[0])
_FRESH = _MINE[1:]
_next_fresh = random.Random(os.getpid()).randrange(len(_FRESH))


def next_ros_domain() -> int:
    """
    Return a ROS domain id for one test's graph: this worker's next, never the run's.

    Returns
    -------
    int
        The next id of this worker's slice (without its first, the worker's ``ROS_DOMAIN_ID``), in
        turn: a test's graph never hears another worker's, nor what the previous tests of this
        worker may have left running.

    """
    global _next_fresh
    domain = _FRESH[_next_fresh % len(_FRESH)]
    _next_fresh += 1
    return domain


@pytest.fixture
def ros_domain() -> int:
    """Return a ROS domain id of this test's own (:func:`next_ros_domain`)."""
    return next_ros_domain()


@pytest.fixture(scope='session')
def ros_domains():
    """Return :func:`next_ros_domain`, for module-scoped fixtures that start ROS graphs."""
    return next_ros_domain


@pytest.fixture
def ros_env(tmp_path, ros_domain):
    """Environment for ROS subprocesses: loopback discovery, a fresh domain id, logs in tmp."""
    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    # a domain of its own: not the worker's ROS_DOMAIN_ID, which in-process nodes use, nor one
    # that another worker or the previous test uses, so that nothing of theirs is ever heard here
    env['ROS_DOMAIN_ID'] = str(ros_domain)
    env['ROS_LOG_DIR'] = str(tmp_path / 'ros_log')
    env['PYTHONUNBUFFERED'] = '1'
    return env


@pytest.fixture
def sim_cli(ros_env, tmp_path):
    """
    Return ``run(*args, env=None, timeout=450)``: ``polarization-compass sim ARGS``, as a user.

    ``python -m polarization_compass.cli sim ARGS`` in a process of its own, in ``tmp_path``, with
    ``ros_env`` (a fresh domain) or ``env``, without ``POLARIZATION_COMPASS_DEBUG`` (a user sees
    one-line errors, not tracebacks); ``run`` returns the completed process, output captured.
    """

    def run(*args, env=None, timeout=450.0):
        env = dict(ros_env if env is None else env)
        env.pop('POLARIZATION_COMPASS_DEBUG', None)
        return subprocess.run(
            [sys.executable, '-m', 'polarization_compass.cli', 'sim', *map(str, args)],
            capture_output=True,
            text=True,
            env=env,
            cwd=tmp_path,
            timeout=timeout,
        )

    return run


class FisheyeSky:
    """
    Simulated raw frames of a level fisheye camera under a Rayleigh sky, and its CAMERA.yaml.

    What the polarizer-convention tests (test_polarizer_gate, test_readout_flip,
    test_polarizer_check) feed the road: an equidistant fisheye (85 deg at the image's half
    width), the sky at DoP 0.7, a sensor of a given 2 x 2 layout and +45 deg direction. Those
    modules import it (``from conftest import FisheyeSky``): their cameras are module constants
    and one test is a hypothesis test, where a fixture cannot reach.
    """

    @staticmethod
    def camera(n_px: int, principal_px=None):
        """
        Return the n x n equidistant fisheye, 90 deg at half the width, its field cut at 85 deg.

        Parameters
        ----------
        n_px : int
            Width and height [px].
        principal_px : tuple of float, optional
            The principal point (1-based column, row) [px]; default the image centre.

        Returns
        -------
        polarization_compass.camera.CameraModel
            The camera.

        """
        import math

        from polarization_compass.camera import CameraModel

        kw = {}
        if principal_px is not None:
            kw = {'principal_x_px': principal_px[0], 'principal_y_px': principal_px[1]}
        return CameraModel(
            model='fisheye_equidistant',
            width_px=n_px,
            height_px=n_px,
            focal_length_mm=(n_px / 2) * 3.45e-3 / (math.pi / 2),
            max_field_angle_deg=85.0,
            **kw,
        )

    @staticmethod
    def mosaic(camera, layout, pol45_toward, bearing_deg, sun_azimuth_deg, sun_altitude_deg, seed):
        """
        Render the raw mosaic of a level camera at ``bearing_deg`` (float32, noise-free sensor).

        Parameters
        ----------
        camera : polarization_compass.camera.CameraModel
            The camera (every pixel is rendered).
        layout : sequence of sequence of float
            The sensor's 2 x 2 polarizer angles [deg], as the sensor labels them.
        pol45_toward : str
            The sensor's +45 deg direction in the image, ``'+x+y'`` or ``'+x-y'``.
        bearing_deg : float
            The camera's bearing [deg] (pitch and roll 0).
        sun_azimuth_deg, sun_altitude_deg : float
            The sun [deg].
        seed : int
            The render's seed.

        Returns
        -------
        numpy.ndarray
            The mosaic, float32, the camera's shape.

        """
        import numpy as np
        from polarization_compass.camera_pixels import PixelSelection
        from polarization_compass.conventions import CameraAttitude
        from polarization_compass.render import Renderer, SunDirection
        from polarization_compass.scene import Scene

        scene = Scene(
            camera=camera,
            pixels=PixelSelection.full(),
            sky={'model': 'rayleigh', 'dop_max': 0.7},
            sensor={'mosaic': {'layout': [list(r) for r in layout], 'pol45_toward': pol45_toward}},
        )
        f = Renderer(scene).render(
            attitude=CameraAttitude(bearing_deg, 0.0, 0.0),
            sun=SunDirection(sun_azimuth_deg, sun_altitude_deg),
            seed=seed,
        )
        return np.asarray(f.mosaic, np.float32)

    @staticmethod
    def camera_yaml(n_px: int, K, extra: str = '') -> str:
        """
        Return the CAMERA.yaml text of an n x n equidistant fisheye with matrix ``K``.

        Parameters
        ----------
        n_px : int
            Width and height [px].
        K : array_like
            The 3 x 3 camera matrix (0-based principal point) [px].
        extra : str
            Lines appended as they are (``polarizer:``, ``readout_flip:``).

        Returns
        -------
        str
            The file's text (no distortion, the field cut at 85 deg).

        """
        import numpy as np

        data = [float(v) for v in np.asarray(K, float).reshape(-1)]
        return (
            f'image_width: {n_px}\nimage_height: {n_px}\n'
            f'camera_matrix: {{rows: 3, cols: 3, data: {data}}}\n'
            'distortion_model: equidistant\n'
            'distortion_coefficients: {rows: 1, cols: 4, data: [0, 0, 0, 0]}\n'
            'max_field_angle_deg: 85\n' + extra
        )


@pytest.fixture(scope='module')
def sunny(tmp_path_factory):
    """
    Return a directory of this module's own holding the real ``sunny`` frame as ``sunny.npz``.

    The Stokes planes ``estimate`` reads (:func:`real_sky.write_stokes_npz`); a test may write its
    camera files beside it.
    """
    import real_sky

    d = tmp_path_factory.mktemp('sunny')
    real_sky.write_stokes_npz(d, 'sunny')
    return d


@pytest.fixture(scope='module')
def ctx():
    """
    Return a private rclpy context per test module, for nodes built in-process.

    No DDS traffic is needed.
    """
    import warnings

    import rclpy
    from rclpy.context import Context

    with warnings.catch_warnings():
        # rclpy's type support imports lark, which imports the deprecated sre_parse (third party)
        warnings.simplefilter('ignore', DeprecationWarning)
        import rosidl_generator_py  # noqa: F401
    c = Context()
    rclpy.init(context=c)
    yield c
    rclpy.shutdown(context=c)


#: launch_testing test files (generate_test_description + unittest classes with
#: proc_output/proc_info): run by launch_testing's pytest plugin where it loads (pytest 7.4,
#: `colcon test` on a robot) and by `launch_test` (`make test`, where the plugin is switched off:
#: it does not load under pytest >= 8).
LAUNCH_TESTING_FILES = {'test_launch_files.py', 'test_fusion_launch.py'}


def pytest_ignore_collect(collection_path, config):
    if collection_path.name in LAUNCH_TESTING_FILES and not config.pluginmanager.has_plugin(
        'launch_testing'
    ):
        return True
    return None
