"""launch_testing tests of sim.launch.py, compass.launch.py and replay.launch.py.

They run where launch_testing is installed (a ROS 2 install, after ``colcon build`` and sourcing the
workspace: ``colcon test --packages-select polarization_compass`` or ``python3 -m pytest
test/test_launch_files.py``). Here launch_testing is not available from any registry, so this module
is skipped and is NOT counted as coverage: the wiring the launch files name is checked without
launch by test_graphs.py, and the same graph runs on DDS in test_nodes_graph.py and through
``polarization-compass sim``.

Each launch file runs with arguments that need no error map (tilt_aware only), so the tests do not
depend on the map shipped with the package: the nodes must start, the sim graph must run to its end
(the launch shuts down with the simulator), and every process must exit with code 0.
"""
import os
import tempfile
import unittest

import pytest

launch_testing = pytest.importorskip("launch_testing")
pytest.importorskip("launch_ros")

import launch  # noqa: E402
import launch_testing.actions  # noqa: E402
import launch_testing.asserts  # noqa: E402
from ament_index_python.packages import get_package_share_directory  # noqa: E402
from launch.actions import IncludeLaunchDescription, SetEnvironmentVariable  # noqa: E402
from launch.launch_description_sources import PythonLaunchDescriptionSource  # noqa: E402

REPORT = tempfile.mkdtemp(prefix="pc_launch_test_")
ARGS = {
    "sim": {"methods": "", "tilt_aware": "true", "turns": "0.05", "turn_rate_deg_s": "36.0", "lockstep": "true",
            "report_dir": REPORT},
    "compass": {"method": "tilt_aware", "site_source": "parameters"},
    "replay": {"methods": "", "tilt_aware": "true", "report_dir": os.path.join(REPORT, "replay")},
}
STARTED = {"sim": "run complete", "compass": "method tilt_aware", "replay": "method tilt_aware"}


@pytest.mark.launch_test
@launch_testing.parametrize("graph", ["sim", "compass", "replay"])
def generate_test_description(graph):
    share = get_package_share_directory("polarization_compass")
    return launch.LaunchDescription([
        SetEnvironmentVariable("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST"),
        IncludeLaunchDescription(PythonLaunchDescriptionSource(os.path.join(share, "launch", f"{graph}.launch.py")),
                                 launch_arguments=ARGS[graph].items()),
        launch_testing.actions.ReadyToTest(),
    ])


class TestGraphRuns(unittest.TestCase):
    def test_nodes_come_up(self, proc_output, graph):
        proc_output.assertWaitFor(STARTED[graph], timeout=180, stream="stderr")


@launch_testing.post_shutdown_test()
class TestGraphStops(unittest.TestCase):
    def test_every_node_exits_cleanly(self, proc_info, graph):
        launch_testing.asserts.assertExitCodes(proc_info, allowable_exit_codes=[0])

    def test_sim_report_is_written(self, graph):
        if graph == "sim":
            self.assertTrue(os.path.isfile(os.path.join(REPORT, "evaluation_summary.json")))
