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
What the camera and the photodiode-array heading nodes share: sun, IMU, queue and outputs.

:class:`HeadingNodeBase` holds the parts of ``heading_estimator`` (a camera) and
``array_heading_estimator`` (a photodiode array) that do not depend on the sensor: the sun source
(site and time parameters, or a NavSatFix), the IMU buffer for the tilt and the 180 deg prior, the
queue of stamped inputs waiting for their IMU sample (:meth:`HeadingNodeBase._drain`), and the
outputs: the heading Imu and bearing of a resolved result, one JSON status per input, failures
included, ``/diagnostics``, the heading as a ``visualization_msgs/Marker`` (``~/heading_marker``)
and a diagnostic picture (``~/debug_image``, rgb8, rendered only while someone subscribes and at
most ``debug_rate_hz``; a sensor that has a picture implements
:meth:`HeadingNodeBase._debug_rgb`). Each node subscribes to its own sensor and turns one queued
input into a :class:`~polarization_compass.estimators.base.HeadingResult`
(:meth:`HeadingNodeBase._estimate`).
"""

from __future__ import annotations

from collections import deque
import json
import math
import threading
import time

from rclpy.node import Node
from rclpy.qos import (
    qos_profile_sensor_data,
    qos_profile_system_default,
    QoSProfile,
    ReliabilityPolicy,
)
from sensor_msgs.msg import Imu, NavSatFix
from std_msgs.msg import Float64, String

from .diagnostics import Diagnostics
from .msgs import heading_imu
from ..bag import decode_orientation, stamp_ns
from ..errors import CompassError
from ..pipeline import AttitudeBuffer, PipelineError, TiltAndPrior
from ..specs import topics
from ..specs.params import apply_fix, sun_source

__all__ = ['HeadingNodeBase']


class HeadingNodeBase(Node):
    """
    The sensor-independent part of a heading node (see the module docstring).

    A subclass calls :meth:`_start_common` once its parameters are read, queues its inputs as
    ``(stamp_ns, data, width, height, t_in, deadline, frame_id)`` in ``self.pending`` and
    implements :meth:`_estimate`.
    """

    #: What one input is, in messages.
    INPUT_NAME = 'input'

    def _start_common(self, p, small_group) -> None:
        """
        Build the sun source, IMU buffer, tilt and prior, diagnostics, publishers and small inputs.

        Parameters
        ----------
        p : ParameterSet
            The node's parameters (``self.params``).
        small_group : rclpy.callback_groups.CallbackGroup
            The callback group of the IMU and NavSatFix subscriptions.

        """
        self.sun = sun_source(p)
        self.imu = AttitudeBuffer(keep_ns=int(max(10.0, 2 * p['prior_max_age_s']) * 1e9))
        self.site_from_fix = None
        self.tilt_prior = TiltAndPrior(
            self.method, p['prior_source'], p['prior_max_age_s'], p['prior_sigma_deg']
        )
        self.needs_tilt = self.tilt_prior.needs_tilt
        self.pending: deque = deque()  # inputs waiting to be processed (tilt_aware: for their IMU)
        self._pending_lock = threading.Lock()
        t = topics.method_topics(self.method)
        self.pub_heading = self.create_publisher(Imu, t['heading_raw'], qos_profile_system_default)
        self.pub_bearing = self.create_publisher(
            Float64, t['bearing_raw'], qos_profile_system_default
        )
        self.pub_status = self.create_publisher(String, t['status'], QoSProfile(depth=50))
        self._start_debug(p)
        if self.tilt_prior.needs_imu:
            # best effort (REP-2003 sensor data): matches reliable and best-effort IMU drivers and
            # bag players alike (a reliable reader never connects to a best-effort writer); deep
            # for fast IMUs
            imu_qos = QoSProfile(depth=topics.IMU_DEPTH, reliability=ReliabilityPolicy.BEST_EFFORT)
            if p.values.get('image_qos') == 'replay':
                # a played bag's IMU reliably (the player publishes reliably): a best-effort
                # sample lost under the image flood leaves tilt_aware's frame without attitude
                imu_qos = QoSProfile(depth=topics.IMU_DEPTH)
            self.create_subscription(
                Imu, topics.IMU, self._on_imu, imu_qos, callback_group=small_group
            )
        if p['site_source'] == 'navsatfix':
            self.create_subscription(
                NavSatFix,
                topics.FIX,
                self._on_fix,
                qos_profile_sensor_data,
                callback_group=small_group,
            )

    def _make_diagnostics(self, label: str) -> None:
        """Create the node's ``/diagnostics`` reporter, titled ``label``."""
        self.diag = Diagnostics(self, label)

    def _warm_up(self, run, first: str) -> None:
        """
        Run the method's start-up warm-up and log how long it took.

        ``run()`` compiles or loads the kernels and returns its seconds. The warm-up is an
        optimisation, never fatal: a failure is logged as a warning, and then the ``first``
        input (an image, a sample) waits for the compilation instead.
        """
        try:
            dt = run()
        except Exception as exc:  # noqa: BLE001 - warm-up is an optimisation, never fatal
            self.get_logger().warning(
                f'warm-up failed ({type(exc).__name__}: {exc}); the first {first} will be slow'
            )
            return
        self.get_logger().info(f'warm-up (kernel compilation or cache load) took {dt:.2f} s')

    # parameters ---------------------------------------------------------------------------------
    def _update_common(self, changed: dict, merged: dict) -> None:
        """Apply run-time changes of the prior and sun parameters (``merged``: all values)."""
        from ..specs.params import SUN_PARAMS

        if {'prior_source', 'prior_max_age_s', 'prior_sigma_deg'} & set(changed):
            self.tilt_prior.prior_source = merged['prior_source']
            self.tilt_prior.prior_max_age_s = float(merged['prior_max_age_s'])
            self.tilt_prior.prior_sigma_deg = float(merged['prior_sigma_deg'])
        if set(SUN_PARAMS) & set(changed):
            self.sun = sun_source(merged)

    # inputs -------------------------------------------------------------------------------------
    def _on_imu(self, msg):
        q = self.diag.decoded('imu', decode_orientation, msg)
        if q is not None:
            self.imu.add(stamp_ns(msg.header), q)
            self._on_imu_extra(msg)

    def _on_imu_extra(self, msg) -> None:
        """Read more of an accepted IMU message (the camera node: its tilt covariance)."""

    def _on_fix(self, msg):
        site = apply_fix(self.sun, self.diag, msg)
        if site is not None:
            self.site_from_fix = site

    def _drain(self) -> None:
        """
        Process waiting inputs.

        tilt_aware needs the IMU at the input's stamp: an input newer than the newest IMU sample
        waits up to imu_max_wait_s (wall) for it, if the IMU stream is live (its newest sample
        within imu_max_wait_s of the stamp) and fewer than three inputs queue.
        """
        wait_ns = self.params['imu_max_wait_s'] * 1e9
        while True:
            with self._pending_lock:
                if not self.pending:
                    return
                t_ns, _, _, _, _, deadline, _ = self.pending[0]
                newest = self.imu.newest_ns
                lagging = newest is not None and t_ns - wait_ns <= newest < t_ns
                if (
                    self.needs_tilt
                    and lagging
                    and time.monotonic() < deadline
                    and len(self.pending) <= 2
                ):
                    return
                item = self.pending.popleft()
            self._process(*item[:5], frame_id=item[6])

    # one input ----------------------------------------------------------------------------------
    def _sun_at(self, t_ns: int):
        """Return the sun (azimuth, altitude) [deg] at the stamp, or as ``time_source`` says."""
        p = self.params
        if p['site_source'] == 'navsatfix' and self.site_from_fix is None:
            raise PipelineError('no NavSatFix received yet (site_source navsatfix)')
        if p['time_source'] == 'stamp':
            return self.sun.at_ns(t_ns)
        if not p['time_utc']:
            raise PipelineError('time_source is parameter but time_utc is empty')
        from ..bag import ns_from_utc
        from ..scene import parse_time_utc

        return self.sun.at_ns(ns_from_utc(parse_time_utc(p['time_utc'])))

    def _tilt_and_prior(self, t_ns: int):
        """Return the IMU's tilt and prior at the stamp (:class:`~..pipeline.TiltAndPrior`)."""
        p = self.params
        inp = self.tilt_prior.inputs(
            t_ns, *self.tilt_prior.lookups(self.imu, t_ns, int(p['imu_tolerance_s'] * 1e9))
        )
        if inp.tilt_missing:
            raise PipelineError(
                f'no IMU sample within {p["imu_tolerance_s"]:g} s of the {self.INPUT_NAME} stamp '
                f'(newest IMU stamp: {self._newest_imu_text()})'
            )
        return inp

    def _prepare(self, data, width, height, t_ns=None):
        """Return what the sensor needs besides the data (the camera node: its camera model)."""
        return None

    def _estimate(self, prepared, data, sun_az, sun_alt, inp, status: dict):
        """Return the heading of one input (a subclass's sensor); may raise PipelineError."""
        raise NotImplementedError

    def _process(
        self, t_ns: int, data, width: int, height: int, t_in: float, frame_id: str | None = None
    ) -> None:
        """Estimate one queued input and publish its heading and status (failures included)."""
        status = {'stamp_ns': t_ns, 'method': self.method}
        try:
            prepared = self._prepare(data, width, height, t_ns=t_ns)
            sun_az, sun_alt = self._sun_at(t_ns)
            inp = self._tilt_and_prior(t_ns)
            t0 = time.perf_counter()
            result = self._estimate(prepared, data, sun_az, sun_alt, inp, status)
            status['estimate_ms'] = round((time.perf_counter() - t0) * 1e3, 3)
        except (PipelineError, CompassError) as exc:
            self.get_logger().warning(
                f'frame {t_ns / 1e9:.3f} s: {exc}', throttle_duration_sec=5.0
            )
            status.update(status='bad_input', reason=str(exc), ok=False, published=False)
            self._publish_status(status)
            self.diag.done(t_in, t_ns, f'bad_input: {exc}', ok=False)
            return
        except Exception as exc:  # noqa: BLE001 - one bad input must not stop the node
            self.diag.reject('estimator_exception', f'{type(exc).__name__}: {exc}')
            status.update(
                status='estimator_exception',
                reason=f'{type(exc).__name__}: {exc}',
                ok=False,
                published=False,
            )
            self._publish_status(status)
            return
        self._publish_result(t_ns, t_in, result, status, sun_az, sun_alt, inp, frame_id)
        self._publish_debug(t_ns, result, prepared, data, (sun_az, sun_alt), inp, frame_id)

    def _publish_result(self, t_ns, t_in, result, status, sun_az, sun_alt, inp, frame_id):
        """Publish a resolved heading (Imu and bearing), the status and the diagnostics."""
        p = self.params
        status.update(
            status=result.status.value,
            reason=result.reason,
            ok=result.ok,
            axial=result.axial,
            bearing_deg=result.bearing_deg,
            yaw_enu_deg=result.yaw_enu_deg,
            psi_deg=result.psi_deg,
            sigma_deg=result.sigma_deg,
            pixels=result.pixels,
            quality=result.quality,
            sun_azimuth_deg=sun_az,
            sun_altitude_deg=sun_alt,
            prior_bearing_deg=inp.prior_bearing_deg,
            resolved_by=result.extras.get('ambiguity_resolved_by'),
            sigma_principal_point_deg=result.extras.get('sigma_principal_point_deg'),
        )
        published = False
        if result.ok and (not result.axial or p['publish_ambiguous']):
            values = (result.yaw_enu_deg, result.sigma_deg, result.bearing_deg)
            if all(v is not None and math.isfinite(v) for v in values):
                sigma = max(float(result.sigma_deg), p['sigma_floor_deg'], 1e-9)
                self.pub_heading.publish(
                    heading_imu(
                        t_ns,
                        frame_id or p['frame_id'],
                        math.radians(result.yaw_enu_deg),
                        math.radians(sigma) ** 2,
                        p['roll_pitch_variance_rad2'],
                    )
                )
                self.pub_bearing.publish(Float64(data=float(result.bearing_deg)))
                published = True
                self.tilt_prior.remember(t_ns, result)
            else:
                self.diag.reject(
                    'non_finite_result', 'the estimator returned a non-finite heading'
                )
        status['published'] = published
        if not published:
            self.get_logger().warning(
                f'frame {t_ns / 1e9:.3f} s not published: {result.status.value}: {result.reason}',
                throttle_duration_sec=5.0,
            )
        self._publish_status(status)
        text = (
            f'{result.status.value}: bearing {result.bearing_deg:.3f} deg, sigma '
            f'{result.sigma_deg:.3g} deg'
            if result.ok
            else f'{result.status.value}: {result.reason}'
        )
        self.diag.extra = {
            'last_bearing_deg': result.bearing_deg if result.ok else '',
            'last_sigma_deg': result.sigma_deg if result.ok else '',
            'sun_altitude_deg': sun_alt,
        }
        self.diag.done(t_in, t_ns, text, ok=published)

    # what the compass sees: marker and debug image --------------------------------------------
    def _start_debug(self, p) -> None:
        """Create the marker and debug-image publishers the parameters ask for."""
        from sensor_msgs.msg import Image

        vals = p.values
        self.pub_marker = self.pub_debug = None
        self._debug_last = -math.inf
        if vals.get('publish_marker', False):
            from visualization_msgs.msg import Marker

            self.pub_marker = self.create_publisher(Marker, '~/heading_marker', 10)
        if vals.get('debug_rate_hz', 0.0) > 0.0:
            self.pub_debug = self.create_publisher(Image, '~/debug_image', 1)

    def _debug_wanted(self) -> bool:
        """Return whether a debug image is due: a subscriber, and the rate allows one now."""
        pub = self.pub_debug
        if pub is None or pub.get_subscription_count() == 0:
            return False
        rate = self.params['debug_rate_hz']
        now = time.monotonic()
        if rate <= 0.0 or now - self._debug_last < 1.0 / rate:
            return False
        self._debug_last = now
        return True

    def _publish_debug(self, t_ns, result, prepared, data, sun, inp, frame_id) -> None:
        """Publish the heading marker and, when due (:meth:`_debug_wanted`), the debug image."""
        frame = frame_id or self.params['frame_id']
        if self.pub_marker is not None and result.ok and result.yaw_enu_deg is not None:
            from .debug_msgs import heading_markers

            for m in heading_markers(t_ns, frame, result.yaw_enu_deg, result.sigma_deg):
                self.pub_marker.publish(m)
        if not self._debug_wanted():
            return
        try:
            rgb = self._debug_rgb(prepared, data, result, sun, inp)
        except Exception as exc:  # noqa: BLE001 - a picture must never stop the compass
            self.diag.reject('debug_image_failed', f'{type(exc).__name__}: {exc}')
            return
        if rgb is not None:
            from .debug_msgs import rgb_image_msg

            self.pub_debug.publish(rgb_image_msg(rgb, t_ns, frame))

    def _debug_rgb(self, prepared, data, result, sun, inp):
        """Return the debug picture of one input (uint8 (H, W, 3)), or None (no picture)."""
        return None

    def _newest_imu_text(self) -> str:
        n = self.imu.newest_ns
        return 'none' if n is None else f'{n / 1e9:.3f} s'

    def _publish_status(self, status: dict) -> None:
        self.pub_status.publish(
            String(data=json.dumps(status, default=_json_default, allow_nan=False))
        )


def _json_default(o):
    try:
        return float(o)
    except (TypeError, ValueError):
        return str(o)
