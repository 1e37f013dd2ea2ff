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
The ``sky_simulator``'s attitude sources and its TF plumbing (a mixin of the node).

The attitude of each frame and IMU sample from the built-in motion, the ``sim/attitude`` topic or
TF (``attitude_source``), the TF listener it needs, the ``motion_tf`` broadcast of the built-in
motion and the ``odom_tf`` broadcaster of the wheel odometry. See
:mod:`polarization_compass.nodes.sky_simulator` for the parameters.
"""

from __future__ import annotations

from .msgs import time_msg
from ..bag import decode_orientation
from ..conventions import (
    matrix_to_quat,
    quat_to_matrix,
    R_BODY_CAM_DEFAULT,
    R_enu_body_from_camera_attitude,
)
from ..errors import MissingDependencyError

__all__ = ['SimulatorAttitude']

#: motion_tf: how far ahead of the stamp looked up the motion is broadcast [simulated s], so that
#: the transforms around a frame's stamp are in the TF buffer before the frame looks them up
MOTION_TF_LEAD_S = 0.5


def _transform(t_ns: int, parent: str, child: str, R):
    """Return the TransformStamped ``parent -> child`` at ``t_ns``: rotation ``R``, no offset."""
    from geometry_msgs.msg import TransformStamped

    tf = TransformStamped()
    tf.header.stamp = time_msg(t_ns)
    tf.header.frame_id = parent
    tf.child_frame_id = child
    q = matrix_to_quat(R)
    r = tf.transform.rotation
    r.x, r.y, r.z, r.w = (float(v) for v in q)
    return tf


class SimulatorAttitude:
    """The attitude sources and TF of the ``sky_simulator`` node (mixed into its class)."""

    def _setup_tf(self):
        try:
            import tf2_ros  # noqa: F401
        except ImportError:
            raise MissingDependencyError(
                'attitude_source tf (tf2_ros)',
                'ros-<distro>-tf2-ros (e.g. sudo apt install ros-jazzy-tf2-ros), or use '
                'attitude_source motion|topic',
            ) from None
        import rclpy
        from tf2_ros import Buffer, TransformListener

        self._tf = Buffer()
        # a node and a thread of its own: a lookup waits for transforms while this node's callback
        # runs (tf2_ros spins the node it is given in its thread: not this one)
        self._tf_node = rclpy.create_node(
            f'{self.get_name()}_tf_listener',
            context=self.context,
            start_parameter_services=False,
            use_global_arguments=False,  # not renamed by the process's -r __node:=...
        )
        self._tf_listener = TransformListener(self._tf, self._tf_node, spin_thread=True)
        if self.params['motion_tf']:
            self._setup_motion_tf()

    def _setup_motion_tf(self):
        """
        Broadcast the built-in motion on TF (``motion_tf``): the sim graph's ground truth.

        The mounting (the default, as with ``motion``) goes out once on ``/tf_static``; the body's
        attitude on ``/tf`` on the IMU's time grid, :data:`MOTION_TF_LEAD_S` ahead of the stamps
        looked up (:meth:`_broadcast_motion`).
        """
        from tf2_ros import StaticTransformBroadcaster, TransformBroadcaster

        self._motion_tf = TransformBroadcaster(self)
        self._motion_tf_k = 0  # next sample of the grid start + k / imu_rate_hz
        self._motion_tf_origin = self.start_ns if self.sim_mode else None
        self._static_tf = StaticTransformBroadcaster(self)
        p = self.params
        self._static_tf.sendTransform(
            _transform(self.start_ns, p['tf_body_frame'], p['camera_frame_id'], R_BODY_CAM_DEFAULT)
        )

    def _broadcast_motion(self, t_ns: int) -> None:
        """Send the motion's transforms up to MOTION_TF_LEAD_S past ``t_ns`` (with motion_tf)."""
        if getattr(self, '_motion_tf', None) is None:
            return
        p = self.params
        if self._motion_tf_origin is None:  # clock_mode system: the motion starts now
            self._motion_tf_origin = int(t_ns)
        step = int(round(1e9 / p['imu_rate_hz']))
        until = int(t_ns) + int(MOTION_TF_LEAD_S * 1e9)
        out = []
        while self._motion_tf_origin + self._motion_tf_k * step <= until:
            t_rel = self._motion_tf_k * step / 1e9
            R = R_enu_body_from_camera_attitude(self.profile.attitude(t_rel))
            out.append(
                _transform(
                    self._motion_tf_origin + self._motion_tf_k * step,
                    p['tf_world_frame'],
                    p['tf_body_frame'],
                    R,
                )
            )
            self._motion_tf_k += 1
        if out:
            self._motion_tf.sendTransform(out)

    def close(self) -> None:
        """Stop the TF listener's thread and node (called once when the node stops)."""
        listener = getattr(self, '_tf_listener', None)
        if listener is None:
            return
        self._tf_listener = None
        listener.executor.shutdown(timeout_sec=2.0)
        listener.dedicated_listener_thread.join(timeout=5.0)
        self._tf_node.destroy_node()

    def _odom_tf_broadcaster(self):
        if not self.params['odom_tf']:
            return None
        try:
            from tf2_ros import TransformBroadcaster
        except ImportError:
            self.get_logger().info('odom_tf: tf2_ros is not installed: odometry/wheel only')
            return None
        return TransformBroadcaster(self)

    # attitude inputs ----------------------------------------------------------------------------
    def _on_attitude(self, msg):
        q = self.diag.decoded('attitude', decode_orientation, msg)
        if q is not None:
            self.R_enu_body_input = quat_to_matrix(q)

    def _attitude_at(self, t_ns: int, t_rel_s: float):
        """R_enu_body at a stamp, or None when the attitude source has nothing yet."""
        if self.attitude_source == 'motion':
            return R_enu_body_from_camera_attitude(self.profile.attitude(t_rel_s))
        if self.attitude_source == 'topic':
            return self.R_enu_body_input
        return self._tf_attitude(t_ns)

    def _tf_attitude(self, t_ns: int):
        """
        Return R_enu_body at ``t_ns`` from TF and set the camera mounting, or None (counted).

        Looks up ``tf_world_frame`` -> ``tf_body_frame`` and -> ``camera_frame_id`` at the stamp
        itself (tf2 interpolates between samples, never extrapolates), waiting up to
        ``tf_timeout_s``: a missing frame is ``tf_missing``, a transform not (yet, or no longer)
        known at the stamp ``tf_stale``.
        """
        from rclpy.duration import Duration
        from rclpy.time import Time
        from tf2_ros import ExtrapolationException

        p = self.params
        self._broadcast_motion(t_ns)
        when = Time(nanoseconds=int(t_ns), clock_type=self.get_clock().clock_type)
        try:
            body = self._tf.lookup_transform(
                p['tf_world_frame'], p['tf_body_frame'], when, Duration(seconds=p['tf_timeout_s'])
            )
            cam = self._tf.lookup_transform(p['tf_world_frame'], p['camera_frame_id'], when)
        except ExtrapolationException as exc:
            self.diag.reject('tf_stale', f'no transform at {t_ns / 1e9:.3f} s: {exc}')
            return None
        except Exception as exc:  # noqa: BLE001 - tf2 raises several lookup exception types
            reason = 'tf_stale' if 'extrapolat' in str(exc).lower() else 'tf_missing'
            self.diag.reject(reason, f'at {t_ns / 1e9:.3f} s: {type(exc).__name__}: {exc}')
            return None

        def R(tr):
            r = tr.transform.rotation
            return quat_to_matrix([r.x, r.y, r.z, r.w])

        R_enu_body = R(body)
        self.R_body_cam = R_enu_body.T @ R(cam)
        return R_enu_body
