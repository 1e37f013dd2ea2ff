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
``sky_simulator``: a simulated polarization camera and IMU under a Rayleigh (or scene) sky.

Publishes (relative names):
  ``camera/image_raw``      sensor_msgs/Image: the raw 2x2 polarizer mosaic of the full sensor,
                            as a camera driver sends it: ``mono16`` (12-bit DN) / ``mono8``, or
                            ``32FC1`` = ideal polarizer intensities in electrons (no noise, no
                            quantisation). Layout from the scene's ``sensor.mosaic`` (default Sony
                            IMX250MZR: 90 45 / 135 0).
  ``camera/camera_info``    intrinsics (same stamp)
  ``imu/data``              sensor_msgs/Imu: body attitude in ENU with noise and bias, angular
                            velocity of the turn, gravity; ``imu_rate_hz``
  ``ground_truth/heading``  sensor_msgs/Imu, the true heading in the estimator's form (yaw only)
  ``gps/fix``               sensor_msgs/NavSatFix of the site, 1 Hz
  ``odometry/wheel``        nav_msgs/Odometry (attitude_source ``motion``), with every IMU sample:
                            a wheel-odometry-like twist in ``imu_frame_id`` (yaw rate of the turn
                            plus ``odom_yaw_rate_bias_deg_s`` and white noise
                            ``odom_yaw_rate_noise_deg_s``, whose variance is the covariance
                            reported; zero linear velocity) and its dead reckoning in ``odom``
                            (starts at yaw 0, drifts with the bias); with ``odom_tf`` also the
                            same ``odom -> imu_frame_id`` transform on ``/tf`` (tf2_ros)
  ``compass_array/intensities`` + ``compass_array/header``  with ``array_geometry`` (or a scene's
                            ``photodiode_array``): each frame's photodiode-array sample
                            (Float32MultiArray) and, published just before it, its std_msgs/Header
                            (the frame's stamp, ``heading_frame_id``), as docs/photodiode-arrays.md
                            asks of an array driver
  ``/clock``                with clock_mode sim
  ``/diagnostics``

Attitude: ``motion`` (built-in turn + tilt schedule), ``topic`` (``sim/attitude``: sensor_msgs/Imu
or geometry_msgs/QuaternionStamped, body orientation in ENU, sample-and-hold) or ``tf`` (needs
tf2_ros): every frame and IMU sample looks up ``tf_world_frame`` -> ``tf_body_frame`` and
``tf_world_frame`` -> ``camera_frame_id`` at its own stamp through a ``tf2_ros.Buffer`` (waiting up
to ``tf_timeout_s``), so the camera's mounting comes from TF too (e.g. a static_transform_publisher
``base_link`` -> ``camera_optical_frame``); a missing or stale transform skips that frame or sample
(``rejected.tf_missing`` / ``rejected.tf_stale`` in /diagnostics, a throttled warning): nothing is
rendered at another attitude. With ``motion_tf`` (the sim graph's ``attitude_source:=tf``) the
node also broadcasts the built-in motion there, as a robot's TF would have it: ``tf_world_frame``
-> ``tf_body_frame`` ahead of the frames and the default mounting on ``/tf_static``; no
``odometry/wheel`` then (its ``odom`` would be a second parent of the body). With ``motion`` and
``topic`` the camera is mounted looking up with its +y axis along body +x
(conventions.R_BODY_CAM_DEFAULT).

Time (clock_mode ``sim``): simulated UTC starts at ``start_time_utc`` and advances at
``time_scale`` times the wall clock; frames are stamped ``start + k / rate_hz`` and never skipped:
when rendering falls more than one frame behind, simulated time slows down (the real-time factor is
in /diagnostics). ``lockstep`` waits for every estimator's status before the next frame. With
clock_mode ``system`` frames are stamped with this node's ROS time and the sun is rendered for it.
"""

from __future__ import annotations

import json
import math
import time

from geometry_msgs.msg import QuaternionStamped
from nav_msgs.msg import Odometry
import numpy as np
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data, qos_profile_system_default, QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, Imu, NavSatFix
from std_msgs.msg import Float32MultiArray, Header, String

from .diagnostics import Diagnostics
from .msgs import (
    array_msg,
    attitude_imu,
    camera_info_msg,
    heading_imu,
    image_msg,
    navsatfix_msg,
    time_msg,
)
from .rosparams import ParameterSet
from .runner import run_node
from .sky_simulator_attitude import SimulatorAttitude
from .sky_simulator_clock import SimulatorClock
from ..bag import ns_from_utc
from ..camera import PixelSelection
from ..conventions import (
    camera_attitude_from_body_quat,
    matrix_to_quat,
    R_BODY_CAM_DEFAULT,
)
from ..errors import CompassError
from ..motion import frame_times_ns, imu_reading, MotionProfile
from ..sensor import sensor_config_for_encoding
from ..simulated_sensors import frame_mosaic, simulation_scene, WheelOdometry
from ..specs import topics
from ..specs.params import SIMULATOR, SUN_PARAMS, sun_source

__all__ = ['SkySimulatorNode', 'main', 'mosaic_config']

GRAVITY_M_S2 = 9.80665
#: Wall-clock rate of the sim-mode scheduler (publishes every frame and IMU sample that is due);
#: /clock goes out at clock_rate_hz, independently.
SCHEDULER_HZ = 100.0
TRUTH_YAW_VARIANCE_RAD2 = 1e-12
#: frame_id of the simulated wheel odometry's dead reckoning (REP-105)
ODOM_FRAME_ID = 'odom'
#: reported variance of the odometry's zero linear velocity [(m/s)^2]: the turn is on the spot
ODOM_LINEAR_VARIANCE_M2_S2 = 1e-4

#: The SensorConfig for an image encoding; the rule is shared with record-sim (sensor.py).
mosaic_config = sensor_config_for_encoding


class SkySimulatorNode(SimulatorAttitude, SimulatorClock, Node):
    """The ``sky_simulator`` node (see the module docstring)."""

    def __init__(self, **kwargs):
        super().__init__('sky_simulator', **kwargs)
        self.params = ParameterSet(self, SIMULATOR, on_change=self._on_change)
        self._setup_sky(self._load_scene())
        self._setup_attitude()
        # compile (or load) the render and sensor kernels and build the ray cache now, not at frame
        # 0
        self._render_frame(self.start_ns, 0, np.eye(3))
        self.diag = Diagnostics(self, 'sky simulator', stale_after_s=1e9)
        self._init_counters()
        self._create_publishers()
        self._create_subscriptions()
        self._start_scheduler()
        self.total_s = self._total_s()
        self._log_start()

    # configuration ------------------------------------------------------------------------------
    def _load_scene(self):
        """Load the scene parameter's scene, with array_geometry's photodiode array when set."""
        return simulation_scene(self.params['scene'], self.params['array_geometry'])

    def _setup_sky(self, scene) -> None:
        """Set up the camera, renderer, sensor, sun, motion and clock of the simulation."""
        p = self.params
        from ..render import Renderer
        from ..scene import parse_time_utc

        self.camera = scene.camera
        self.renderer = Renderer(scene.replace(sensor={}), pixels=PixelSelection.full())
        self.sensor_cfg = sensor_config_for_encoding(scene.sensor, p['encoding'])
        self.sun = sun_source(p)
        self.profile = self._profile()
        self.sim_mode = p['clock_mode'] == 'sim'
        self.start_ns = ns_from_utc(parse_time_utc(p['start_time_utc']))

    def _setup_attitude(self) -> None:
        """Set up the attitude source's state (and the TF listener with attitude_source tf)."""
        self.attitude_source = self.params['attitude_source']
        self.R_enu_body_input = None  # topic / tf attitude (sample and hold)
        self.R_body_cam = R_BODY_CAM_DEFAULT  # the mounting (from TF with attitude_source tf)
        self._tf = None
        if self.attitude_source == 'tf':
            self._setup_tf()

    def _init_counters(self) -> None:
        """Zero the frame and sample counters of /diagnostics and the render-ahead state."""
        self.frames = 0
        self.frames_skipped = 0
        self.imu_samples = 0
        self.late_frames = 0
        self.lockstep_timeouts = 0
        self.render_ms = []
        self.prepared = None  # (stamp, k, image msg, attitude, sun altitude, ms) rendered ahead
        self.last_frame_wall = None
        self.frames_ahead = 0

    def _create_publishers(self) -> None:
        """Create the camera, array, IMU, truth, GPS, odometry, frame and clock publishers."""
        p = self.params
        img_qos = qos_profile_system_default
        self.pub_image = self.create_publisher(Image, topics.IMAGE, img_qos)
        self.pub_array = (
            self.create_publisher(Float32MultiArray, topics.ARRAY, img_qos)
            if self.renderer.array is not None
            else None
        )
        self.pub_array_header = (
            self.create_publisher(Header, topics.ARRAY_HEADER, img_qos)
            if self.renderer.array is not None
            else None
        )
        self.pub_info = self.create_publisher(CameraInfo, topics.CAMERA_INFO, img_qos)
        self.pub_imu = self.create_publisher(Imu, topics.IMU, qos_profile_system_default)
        self.pub_truth = self.create_publisher(Imu, topics.TRUTH, qos_profile_system_default)
        self.pub_fix = self.create_publisher(NavSatFix, topics.FIX, qos_profile_system_default)
        self.pub_odom = (
            self.create_publisher(Odometry, topics.ODOM, qos_profile_system_default)
            if self.attitude_source == 'motion'
            else None
        )
        self.odom = WheelOdometry()  # dead reckoning of the odometry's yaw rate, in odom
        self.rng_odom = np.random.default_rng([p['seed'], 11])
        self.odom_tf = self._odom_tf_broadcaster() if self.pub_odom is not None else None
        self.pub_frames = self.create_publisher(String, topics.FRAMES, QoSProfile(depth=50))
        self.pub_clock = (
            self.create_publisher(Clock, topics.CLOCK, QoSProfile(depth=10))
            if self.sim_mode
            else None
        )

    def _create_subscriptions(self) -> None:
        """Subscribe to the attitude input (attitude_source topic) and the lockstep statuses."""
        p = self.params
        if self.attitude_source == 'topic':
            t = Imu if p['attitude_topic_type'] == 'imu' else QuaternionStamped
            self.create_subscription(
                t, topics.ATTITUDE_IN, self._on_attitude, qos_profile_sensor_data
            )

        self.lock_topics = [t for t in p['lockstep_topics'] if t] if p['lockstep'] else []
        self.acks = dict.fromkeys(self.lock_topics, -1)
        for t in self.lock_topics:
            self.create_subscription(
                String, t, lambda m, tt=t: self._on_ack(tt, m), QoSProfile(depth=50)
            )

    def _start_scheduler(self) -> None:
        """Set up the scheduler's state and timers (sim: one wall-clock tick; system: two)."""
        p = self.params
        self.waiting_for = None  # (stamp, wall start) while waiting in lockstep
        self.k_frame = 0
        self.k_imu = 0
        self.done_wall = None
        self.started = False
        self.t_primed = None
        self.t_wait0 = time.monotonic()
        self.rng_imu = np.random.default_rng([p['seed'], 7])
        from .diagnostics import _wall_clock

        if self.sim_mode:
            self.sim_cursor = self.start_ns
            self.base = None  # (sim ns, wall s)
            self.last_clock_wall = -math.inf
            self.create_timer(1.0 / SCHEDULER_HZ, self._tick_sim, clock=_wall_clock())
        else:
            self.t_first_ns = None
            self.create_timer(1.0 / p['rate_hz'], self._frame_system)
            self.create_timer(1.0 / p['imu_rate_hz'], self._imu_system)

    def _total_s(self):
        """Return the seconds to simulate: the motion's, duration_s, or None (until stopped)."""
        p = self.params
        return (
            self.profile.total_s()
            if self.attitude_source == 'motion'
            else (p['duration_s'] or None)
        )

    def _log_start(self) -> None:
        """Log what is simulated: encoding, image size, rate, attitude, clock and length."""
        p = self.params
        total = self.total_s
        self.get_logger().info(
            f'{p["encoding"]} {self.camera.width_px}x{self.camera.height_px} at {p["rate_hz"]:g} '
            'Hz, '
            f'attitude {self.attitude_source}, clock {p["clock_mode"]}'
            + (f', {total:g} s simulated' if total else ', until stopped')
        )

    def _profile(self) -> MotionProfile:
        p = self.params.values
        return MotionProfile(
            p['start_bearing_deg'],
            p['turn_rate_deg_s'],
            p['pitch_deg'],
            p['roll_deg'],
            p['pitch_amplitude_deg'],
            p['roll_amplitude_deg'],
            p['tilt_period_s'],
            p['turns'],
            p['duration_s'],
        )

    def _on_change(self, changed: dict):
        if not hasattr(self, 'profile'):
            return None
        merged = {**self.params.values, **changed}
        if set(SUN_PARAMS) & set(changed):
            try:
                self.sun = sun_source(merged)
            except CompassError as exc:
                return str(exc)
        if 'time_scale' in changed and getattr(self, 'base', None) is not None:
            # simulated time runs on from where it is at the new rate (no jump): restart the wall
            # base now
            self.base = (self.sim_cursor, time.monotonic())
        self.params.values.update(changed)
        self.profile = self._profile()
        return None

    # outputs ------------------------------------------------------------------------------------
    def _publish_imu(self, t_ns: int, R_enu_body) -> None:
        p = self.params
        R, variances = imu_reading(
            R_enu_body,
            self.rng_imu.standard_normal(3),
            p['imu_attitude_noise_deg'],
            p['imu_yaw_noise_deg'],
            p['imu_yaw_bias_deg'],
            p['imu_roll_bias_deg'],
            p['imu_pitch_bias_deg'],
        )
        w_body = (
            R_enu_body.T @ np.array([0.0, 0.0, self.profile.yaw_rate_enu_rad_s()])
            if self.attitude_source == 'motion'
            else None
        )
        g_body = R_enu_body.T @ np.array([0.0, 0.0, GRAVITY_M_S2])
        self.pub_imu.publish(attitude_imu(t_ns, p['imu_frame_id'], R, variances, w_body, g_body))
        self.imu_samples += 1
        if self.pub_odom is not None:
            self._publish_odometry(t_ns)

    def _publish_odometry(self, t_ns: int) -> None:
        """Publish the wheel odometry of the turn at ``t_ns`` (and its odom TF, see the module)."""
        p = self.params
        sigma = math.radians(p['odom_yaw_rate_noise_deg_s'])
        w = (
            self.profile.yaw_rate_enu_rad_s()
            + math.radians(p['odom_yaw_rate_bias_deg_s'])
            + sigma * float(self.rng_odom.standard_normal())
        )
        yaw_rad = self.odom.step(t_ns, w)
        m = Odometry()
        m.header.stamp = time_msg(t_ns)
        m.header.frame_id = ODOM_FRAME_ID
        m.child_frame_id = p['imu_frame_id']
        q = m.pose.pose.orientation
        q.z, q.w = math.sin(yaw_rad / 2.0), math.cos(yaw_rad / 2.0)
        m.pose.covariance = [1e3 if i % 7 == 0 else 0.0 for i in range(36)]  # not to be fused
        m.twist.twist.angular.z = w
        cov = [0.0] * 36
        cov[0] = cov[7] = cov[14] = ODOM_LINEAR_VARIANCE_M2_S2
        cov[21] = cov[28] = 1e3  # roll and pitch rates: not measured
        cov[35] = max(sigma * sigma, 1e-12)
        m.twist.covariance = cov
        self.pub_odom.publish(m)
        if self.odom_tf is not None:
            from geometry_msgs.msg import TransformStamped

            tf = TransformStamped()
            tf.header = m.header
            tf.child_frame_id = m.child_frame_id
            tf.transform.rotation = m.pose.pose.orientation
            self.odom_tf.sendTransform(tf)

    def _render_frame(self, t_ns: int, k_frame: int, R_enu_body):
        """
        Render frame ``k_frame`` at ``t_ns`` into its messages and time it.

        Returns the (image, array sample or None) messages, the camera attitude, the sun's
        altitude [deg] and the CPU-side wall time it took [ms].
        """
        p = self.params
        t0 = time.perf_counter()
        att = camera_attitude_from_body_quat(matrix_to_quat(R_enu_body), self.R_body_cam)
        az, alt = self.sun.at_ns(t_ns)
        rng = np.random.default_rng([p['seed'], k_frame])
        mosaic, array_intensities = frame_mosaic(
            self.renderer, self.sensor_cfg, p['encoding'], att, (az, alt), rng
        )
        msg = (
            image_msg(mosaic, t_ns, p['camera_frame_id']),
            None if array_intensities is None else array_msg(array_intensities),
        )
        return msg, att, alt, (time.perf_counter() - t0) * 1e3

    def _prepare_next_frame(self, now: float) -> None:
        """
        Render the next frame ahead of its time when the motion is known.

        With the built-in motion the next frame's attitude is known: render it once half a period
        has passed since the last frame went out, so that at its time only the publishing is left
        (a camera's frame rate does not depend on what the computer receiving its images is doing).
        """
        if (
            self.attitude_source != 'motion'
            or self.prepared is not None
            or self.last_frame_wall is None
        ):
            return
        p = self.params
        if now - self.last_frame_wall < 0.5 / (p['rate_hz'] * p['time_scale']):
            return
        t = frame_times_ns(self.start_ns, p['rate_hz'], self.total_s, self.k_frame)
        if t is None:
            return
        R = self._attitude_at(t, (t - self.start_ns) / 1e9)
        self.prepared = (t, self.k_frame) + self._render_frame(t, self.k_frame, R)

    def _publish_frame(self, t_ns: int, R_enu_body) -> None:
        p = self.params
        t0 = time.perf_counter()
        ahead = self.prepared is not None and self.prepared[:2] == (t_ns, self.k_frame)
        if ahead:
            _, _, img, att, alt, render_ms = self.prepared
        else:
            img, att, alt, render_ms = self._render_frame(t_ns, self.k_frame, R_enu_body)
        self.prepared = None
        if self.frames % max(1, int(round(p['rate_hz']))) == 0:
            self.pub_fix.publish(
                navsatfix_msg(p['latitude_deg'], p['longitude_deg'], p['altitude_m'], t_ns, 'gps')
            )
        yaw_enu = math.atan2(R_enu_body[1, 0], R_enu_body[0, 0])
        self.pub_truth.publish(
            heading_imu(t_ns, p['heading_frame_id'], yaw_enu, TRUTH_YAW_VARIANCE_RAD2, 1e-12)
        )
        self.pub_info.publish(camera_info_msg(self.camera, t_ns, p['camera_frame_id']))
        self.pub_image.publish(img[0])
        if img[1] is not None:  # the header first, then its sample (paired by publication time)
            self.pub_array_header.publish(
                Header(stamp=time_msg(t_ns), frame_id=p['heading_frame_id'])
            )
            self.pub_array.publish(img[1])
        self.pub_frames.publish(
            String(data=json.dumps({'stamp_ns': int(t_ns), 'wall_ns': time.time_ns()}))
        )
        self.frames += 1
        self.last_frame_wall = time.monotonic()
        self.frames_ahead += ahead
        # wall time to make and send the frame (its rendering too, when that was done ahead)
        self.render_ms.append((time.perf_counter() - t0) * 1e3 + (render_ms if ahead else 0.0))
        self.diag.extra = {
            'frames': self.frames,
            'frames_rendered_ahead': self.frames_ahead,
            'frames_skipped': self.frames_skipped,
            'imu_samples': self.imu_samples,
            'late_frames': self.late_frames,
            'lockstep_timeouts': self.lockstep_timeouts,
            'frame_ms_p95': float(np.percentile(self.render_ms[-200:], 95)),
            'true_bearing_deg': att.bearing_deg,
            'sun_altitude_deg': alt,
        }
        self.diag.last_status = f'frame {self.frames} bearing {att.bearing_deg:.2f} deg'
        if self.frames % 25 == 0:
            n = (
                ''
                if self.total_s is None
                else f'/{int(math.ceil(self.total_s * p["rate_hz"] - 1e-9))}'
            )
            self.get_logger().info(f'frame {self.frames}{n}')

    def _skip_frame(self) -> None:
        """Count a frame without an attitude (tf: the lookup counted why)."""
        if self.attitude_source != 'tf':
            self.diag.reject('no_attitude', 'no attitude received yet: frame skipped')
        self.frames_skipped += 1
        self.diag.extra = {**self.diag.extra, 'frames_skipped': self.frames_skipped}


def main(argv=None) -> int:
    return run_node(SkySimulatorNode, 'sky_simulator', argv)


if __name__ == '__main__':
    raise SystemExit(main())
