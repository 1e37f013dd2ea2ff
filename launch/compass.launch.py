"""A real polarization camera and IMU: heading_estimator (method) and its tilt_corrector. The input
topics are launch arguments (remappings); the output is compass/<method>/heading (sensor_msgs/Imu for
robot_localization, see config/ekf_heading_example.yaml and docs/ros.md).

    ros2 launch polarization_compass compass.launch.py method:=least_squares \
        image_topic:=/pol_camera/image_raw camera_info_topic:=/pol_camera/camera_info imu_topic:=/imu/data

The nodes, parameter files and remappings come from polarization_compass.graphs (the single
description of each graph); launch and launch_ros are imported only when the launch runs.
"""


def generate_launch_description():
    from polarization_compass.graphs import launch_description
    return launch_description("compass")
