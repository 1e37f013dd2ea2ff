# shellcheck shell=bash
# Sourced by `make test` (source tools/ros_cpp_env.sh VENV): when VENV has ../shared/ros-cpp installed
# (robot_localization's ekf_node, tf2_ros, static_transform_publisher, cv_bridge), source its
# setup.bash so that the tests that need those run, and say so in one line; otherwise say in one line
# that those tests are skipped. On a robot (ROS from apt, `colcon test`) the same tests find the tools
# through the sourced ROS install and this file is not used.
_pc_venv="${1:-.venv}"
if [ -f "$_pc_venv/opt/ros-cpp/setup.bash" ]; then
  # shellcheck disable=SC1091
  source "$_pc_venv/opt/ros-cpp/setup.bash"
  echo "make test: robot_localization / tf2_ros tests use $_pc_venv/opt/ros-cpp (setup.bash sourced)"
elif ! "$_pc_venv/bin/python" -c 'import tf2_ros' >/dev/null 2>&1; then
  echo "make test: robot_localization / tf2_ros tests SKIPPED: no ekf_node, tf2_ros here" \
       "(a ROS install has them; here: ../shared/ros-cpp/install.sh $_pc_venv --with-cv-bridge)"
fi
unset _pc_venv
