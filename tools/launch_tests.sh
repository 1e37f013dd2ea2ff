#!/usr/bin/env bash
# The launch_testing tests (test/test_launch_files.py) with launch_testing's own runner `launch_test`,
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
colcon build --packages-select polarization_compass --build-base "$ws/build" --install-base "$ws/install" \
  --event-handlers console_direct- >"$ws/colcon.log" 2>&1 || { cat "$ws/colcon.log"; exit 1; }
set +u
# shellcheck disable=SC1091
source "$ws/install/setup.bash"
set -u
export ROS_LOG_DIR="$ws/ros_log"
launch_test test/test_launch_files.py
