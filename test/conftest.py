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

Test-wide settings: numpy floating-point errors raise, hypothesis is deterministic and bounded, and
every ROS process stays on loopback with a domain id of its own.
"""

import os
import random

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

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random(os.getpid()).randint(100, 200)))


@pytest.fixture
def ros_env(tmp_path):
    """Environment for ROS subprocesses: loopback discovery, a fresh domain id, logs in tmp."""
    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    # a domain of its own: not the one the Makefile exports for the whole run (73), which other
    # tests' graphs use, so that nothing left of another test is ever heard here
    taken = os.environ.get('ROS_DOMAIN_ID')
    env['ROS_DOMAIN_ID'] = str(random.choice([d for d in range(1, 101) if str(d) != taken]))
    env['ROS_LOG_DIR'] = str(tmp_path / 'ros_log')
    env['PYTHONUNBUFFERED'] = '1'
    return env


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
