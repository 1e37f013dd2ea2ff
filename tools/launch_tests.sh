#!/usr/bin/env bash
# The launch_testing tests (test/test_launch_files.py, and test/test_fusion_launch.py where
# robot_localization is installed) with launch_testing's own runner `launch_test`,
# against an install space built here with colcon (what `ros2 launch` on a robot uses). Called by
# `make test` when the venv has launch, launch_ros and launch_testing (e.g. after
# ../shared/ros-launch/install.sh .venv); says so and does nothing otherwise.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV="${VENV:-.venv}"
if ! "$VENV/bin/python" -c "import launch, launch_ros, launch_testing" >/dev/null 2>&1 || [ ! -x "$VENV/bin/launch_test" ]; then
  echo "make test: launch tests SKIPPED: launch, launch_ros and launch_testing are not installed in $VENV" \
       "(a ROS 2 install has them; here: ../shared/ros-launch/install.sh $VENV)"
  exit 0
fi
export PATH="$PWD/$VENV/bin:$PATH"
ws="$(mktemp -d "${TMPDIR:-/tmp}/pc_launch_ws.XXXXXX")"
trap 'rm -rf "$ws"' EXIT
echo "make test: launch tests: colcon build into $ws, then launch_test test/test_launch_files.py"
colcon --log-base "$ws/log" build --packages-select polarization_compass --build-base "$ws/build" \
  --install-base "$ws/install" --event-handlers console_direct- >"$ws/colcon.log" 2>&1 \
  || { cat "$ws/colcon.log"; exit 1; }
set +u
# shellcheck disable=SC1091
source "$ws/install/setup.bash"
set -u
export ROS_LOG_DIR="$ws/ros_log"
launch_test test/test_launch_files.py
# robot_localization's ekf_node fusing the heading (fusion.launch.py): where it is installed (a ROS
# install; here ../shared/ros-cpp, whose setup.bash `make test` has sourced). After the launch-file
# tests, not beside them: side by side on two cores the sim graph's evaluator lost 3 of its 5 truth
# frames (clean-clone run, 2026-11-29 00:22), and the two runs together save only about a minute.
if python -c "from ament_index_python.packages import get_package_prefix as g; g('robot_localization')" \
    >/dev/null 2>&1; then
  echo "make test: launch tests: launch_test test/test_fusion_launch.py (robot_localization's ekf_node)"
  launch_test test/test_fusion_launch.py
else
  echo "make test: fusion launch test SKIPPED: robot_localization is not installed" \
       "(a ROS install has it; here: ../shared/ros-cpp/install.sh $VENV --with-cv-bridge)"
fi
