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
launch_testing tests of the launch files from an install space.

launch_testing tests of sim.launch.py, compass.launch.py and replay.launch.py from an install
space.

Run by launch_testing's own runner (``make test`` -> tools/launch_tests.sh: ``colcon build`` into a
temporary install space, source it, ``launch_test test/test_launch_files.py``) and, on a robot, by
``colcon test`` (pytest 7.4 with launch_testing's plugin). Under pytest >= 8 the plugin does not
load and conftest.py leaves this file out (launch_test runs it). Without the launch packages it is
skipped: ``make test`` says so, and it is then NOT coverage.

Each launch file runs with arguments that need no error map (tilt_aware only): the nodes must
start, the sim graph must run to its end with its defaults (lockstep: every frame answered) and
shut down with the simulator, every process must exit with code 0, and the sim report must be
complete. test_ros2_launch.py drives ``ros2 launch`` from outside (Ctrl-C, --show-args, ros2 param,
live camera).
"""

import json
import os
import tempfile
import unittest

import pytest

launch_testing = pytest.importorskip('launch_testing')
pytest.importorskip('launch_ros')

# after the importorskip calls above, hence E402 (not at the top) and I100 (after pytest)
from ament_index_python.packages import get_package_share_directory  # noqa: E402, I100
import launch  # noqa: E402
from launch.actions import IncludeLaunchDescription, SetEnvironmentVariable  # noqa: E402
from launch.launch_description_sources import PythonLaunchDescriptionSource  # noqa: E402
import launch_testing.actions  # noqa: E402
import launch_testing.asserts  # noqa: E402

REPORT = tempfile.mkdtemp(prefix='pc_launch_test_')
ARGS = {
    # 0.05 turn at 36 deg/s: 0.5 s simulated, frames at 0.0 .. 0.4 s (5); lockstep is the default
    'sim': {
        'methods': '',
        'tilt_aware': 'true',
        'turns': '0.05',
        'turn_rate_deg_s': '36.0',
        'report_dir': REPORT,
    },
    'compass': {'method': 'tilt_aware', 'site_source': 'parameters'},
    'replay': {'methods': '', 'tilt_aware': 'true', 'report_dir': os.path.join(REPORT, 'replay')},
}
STARTED = {'sim': 'run complete', 'compass': 'method tilt_aware', 'replay': 'method tilt_aware'}


@pytest.mark.launch_test
@launch_testing.parametrize('graph', ['sim', 'compass', 'replay'])
def generate_test_description(graph):
    share = get_package_share_directory('polarization_compass')
    return launch.LaunchDescription(
        [
            SetEnvironmentVariable('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST'),
            IncludeLaunchDescription(
                PythonLaunchDescriptionSource(os.path.join(share, 'launch', f'{graph}.launch.py')),
                launch_arguments=ARGS[graph].items(),
            ),
            launch_testing.actions.ReadyToTest(),
        ]
    )


class TestGraphRuns(unittest.TestCase):
    """Checks while the graph runs."""

    def test_nodes_come_up(self, proc_output, graph):
        proc_output.assertWaitFor(STARTED[graph], timeout=180, stream='stderr')


@launch_testing.post_shutdown_test()
class TestGraphStops(unittest.TestCase):
    """Checks after the graph has shut down."""

    def test_every_node_exits_cleanly(self, proc_info, graph):
        launch_testing.asserts.assertExitCodes(proc_info, allowable_exit_codes=[0])

    def test_sim_report_is_written_and_complete(self, graph):
        if graph != 'sim':
            return
        with open(os.path.join(REPORT, 'evaluation_summary.json')) as f:
            s = json.load(f)
        # on a failure, which frames were scored tells a loss at the start (discovery) from one
        # at the end (the stop)
        with open(os.path.join(REPORT, 'evaluation_samples.csv')) as f:
            seen = f.read()
        why = json.dumps(s['streams'], sort_keys=True) + '\nsamples:\n' + seen
        self.assertTrue(s['complete'], why)
        self.assertEqual(s['truth_frames'], 5, why)
        self.assertEqual(
            (s['streams']['tilt_aware/raw']['count'], s['streams']['tilt_aware/raw']['missed']),
            (5, 0),
            why,
        )
        self.assertGreater(os.path.getsize(os.path.join(REPORT, 'evaluation.png')), 0)
