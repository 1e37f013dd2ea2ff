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

r"""
Launch a real polarization camera and IMU: heading_estimator (method) and its tilt_corrector.

The input topics are launch arguments (remappings); the output is compass/<method>/heading
(sensor_msgs/Imu for robot_localization, see config/ekf_heading_example.yaml and docs/ros.md)::

    ros2 launch polarization_compass compass.launch.py method:=least_squares \
        image_topic:=/pol_camera/image_raw camera_info_topic:=/pol_camera/camera_info \
        imu_topic:=/imu/data

Full-resolution images: this launch points Fast DDS at the package's shared-memory profile
(large_image_transport, default true; false when the camera is on another machine). The camera
driver must publish with the same profile (start it with FASTDDS_DEFAULT_PROFILES_FILE set to
share/polarization_compass/config/fastdds_large_images.xml): with Fast DDS's default transports
on the driver's side 10 MB best-effort images are lost in fragments (docs/ros.md).

Nodes started with the default arguments (generated from polarization_compass.graphs;
test/test_launch_docs.py keeps this list current; `--show-args` lists the arguments):

    heading_estimator  heading_estimator_least_squares
    tilt_corrector     tilt_corrector_least_squares

The nodes, parameter files and remappings come from polarization_compass.graphs (the single
description of each graph); launch and launch_ros are imported only when the launch runs.
"""


def generate_launch_description():
    from polarization_compass.graphs import launch_description

    return launch_description('compass')
