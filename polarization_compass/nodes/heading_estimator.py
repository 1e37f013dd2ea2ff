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
``heading_estimator``: heading from a polarization camera, one node per method.

Subscribes (relative names, remappable):
  ``camera/image_raw``   sensor_msgs/Image, raw 2x2 mosaic (mono8/mono16, or 32FC1 ideal
                         intensities), sensor-data QoS (REP-2003)
  ``camera/camera_info`` intrinsics (parameters until the first one arrives, or always:
                         camera_info_source)
  ``compass_array/intensities`` instead of the two above when ``input`` is ``array``: a
                         photodiode-array compass, std_msgs/Float32MultiArray, units x channels
                         row-major (layout.dim empty or [units, channels]). Geometry from
                         ``array_geometry``.
  ``compass_array/header`` std_msgs/Header published beside each array sample (``array_stamp:
                         header``, the default): the sample takes its stamp and frame_id
                         (stamp_pairing.py); with ``array_stamp: arrival`` a sample is stamped with
                         this node's clock on arrival.
  ``imu/data``           sensor_msgs/Imu: the tilt for tilt_aware and the ambiguity prior
                         (prior_source imu); its orientation_covariance (plus
                         ``attitude_sigma_deg``) grows tilt_aware's sigma by ``J Sigma_att J^T``
                         (docs/ros.md, "Attitude uncertainty")
  ``gps/fix``            sensor_msgs/NavSatFix when site_source is navsatfix
Publishes, stamped with the image's header.stamp:
  ``compass/<method>/heading_raw``      sensor_msgs/Imu as robot_localization fuses it (see
                                        nodes.msgs)
  ``compass/<method>/bearing_raw_deg``  std_msgs/Float64, true bearing of camera +y (= body +x),
                                        deg
  ``compass/<method>/status``           std_msgs/String, JSON, one per image, failures included
  ``/diagnostics``
Headings known only modulo 180 deg are not published on the Imu/Float64 topics unless
``publish_ambiguous`` is true; their status says so.
"""

from __future__ import annotations

from collections import deque
import dataclasses
import json
import math
import threading
import time

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.qos import (
    qos_profile_sensor_data,
    qos_profile_system_default,
    QoSProfile,
    ReliabilityPolicy,
)
from sensor_msgs.msg import CameraInfo, Image, Imu, NavSatFix
from std_msgs.msg import Float32MultiArray, Float64, Header, String

from .diagnostics import Diagnostics
from .msgs import AttitudeUncertainty, decode_image, heading_imu
from .rosparams import ParameterSet
from .runner import run_node
from ..bag import decode_camera_info, decode_orientation, MessageError, stamp_ns
from ..camera import CameraError, CameraModel
from ..errors import CompassError
from ..estimators import registry
from ..pipeline import (
    AttitudeBuffer,
    CameraInfoState,
    HeadingFrontEnd,
    ImageLossWatch,
    PipelineError,
    PolarizerMonitor,
    TiltAndPrior,
    warm_up,
)
from ..specs import topics
from ..specs.params import (
    apply_fix,
    ESTIMATOR,
    knob_params,
    knob_values,
    layout_from_text,
    SUN_PARAMS,
    sun_source,
)

__all__ = ['HeadingEstimatorNode', 'main', 'MAX_PENDING_IMAGES']

#: Decoded images waiting to be processed; beyond, the oldest is dropped and counted
#: (image_queue_full).
MAX_PENDING_IMAGES = 8


class HeadingEstimatorNode(Node):
    """The ``heading_estimator`` node (see the module docstring)."""

    def __init__(self, **kwargs):
        super().__init__('heading_estimator', **kwargs)
        self.front = None
        self.params = ParameterSet(self, ESTIMATOR, on_change=self._on_change)
        self.method = self.params['method']
        p = self.params
        self.array = None
        self._array_geometry = None
        self.pairer = None  # array_stamp header: pairs each array sample with its header
        self._knob_specs = None  # None: the image method's knobs; a photodiode array's otherwise
        if p['input'] == 'array':
            from ..photodiode.geometry import load_array_geometry
            from ..photodiode.heading import ARRAY_KNOBS

            if not p['array_geometry']:
                raise CompassError('input array needs array_geometry (a sensor description YAML)')
            self._array_geometry = load_array_geometry(p['array_geometry'])
            self._knob_specs = ARRAY_KNOBS
        try:
            knobs = knob_params(self.method, self._knob_specs)
        except CompassError as exc:
            raise CompassError(f'method {self.method!r}: {exc}') from None
        self.knob_set = ParameterSet(self, knobs, on_change=self._on_knob_change)
        self.front = HeadingFrontEnd(
            self.method,
            {} if self.array_input else knob_values(self.method, self.knob_set.values),
            layout_from_text(p['polarizer_layout']),
            p['pol45_toward'],
            p['demosaic'],
            p['use_intensity'],
            p['sky_check'],
        )
        if self.array_input:
            self.array = self._make_array(self.knob_set.values)
        else:
            try:
                dt = warm_up(self.front, camera=self._fallback_camera_or_none())
                self.get_logger().info(
                    f'warm-up (kernel compilation or cache load) took {dt:.2f} s'
                )
            except Exception as exc:  # noqa: BLE001 - warm-up is an optimisation, never fatal
                self.get_logger().warning(
                    f'warm-up failed ({type(exc).__name__}: {exc}); the first image will be slow'
                )
        self.sun = sun_source(p)
        self.imu = AttitudeBuffer(keep_ns=int(max(10.0, 2 * p['prior_max_age_s']) * 1e9))
        self.camera_info = (
            CameraInfoState()
        )  # validated intrinsics from camera_info, or why there are none
        self.loss = ImageLossWatch()  # images that never arrived (camera_info without its image)
        self.site_from_fix = None
        self.tilt_prior = TiltAndPrior(
            self.method, p['prior_source'], p['prior_max_age_s'], p['prior_sigma_deg']
        )
        self.needs_tilt = self.tilt_prior.needs_tilt
        self.attitude_uncertainty = AttitudeUncertainty()  # the latest IMU's tilt variance
        self.pending: deque = (
            deque()
        )  # decoded images waiting to be processed (tilt_aware: for their IMU)
        self._pending_lock = threading.Lock()
        self.diag = Diagnostics(self, f'heading estimator ({self.method})')
        self.polarizer = PolarizerMonitor(p['polarizer_check_every'])

        t = topics.method_topics(self.method)
        self.pub_heading = self.create_publisher(Imu, t['heading_raw'], qos_profile_system_default)
        self.pub_bearing = self.create_publisher(
            Float64, t['bearing_raw'], qos_profile_system_default
        )
        self.pub_status = self.create_publisher(String, t['status'], QoSProfile(depth=50))
        # Images are received (decoded and queued) in the executor and processed in this node's own
        # worker thread (:meth:`_work`), whatever the executor (the default EventsExecutor is
        # single-threaded): a long estimate never blocks reception, so the middleware's 5-deep
        # image queue does not overflow silently under a flood; our queue (MAX_PENDING_IMAGES)
        # drops the oldest image when full and counts it (rejected.image_queue_full in
        # /diagnostics). With the Python executors, two threads: images in one group, the small
        # inputs (IMU, camera_info, fix) in another.
        self.executor_threads = 2
        small, images = MutuallyExclusiveCallbackGroup(), MutuallyExclusiveCallbackGroup()
        self._work_cv = threading.Condition()
        self._worker = None
        self._stop = False
        if self.tilt_prior.needs_imu:
            # best effort (REP-2003 sensor data): matches reliable and best-effort IMU drivers and
            # bag players alike (a reliable reader never connects to a best-effort writer); deep
            # for fast IMUs
            imu_qos = QoSProfile(depth=topics.IMU_DEPTH, reliability=ReliabilityPolicy.BEST_EFFORT)
            self.create_subscription(Imu, topics.IMU, self._on_imu, imu_qos, callback_group=small)
        if p['site_source'] == 'navsatfix':
            self.create_subscription(
                NavSatFix, topics.FIX, self._on_fix, qos_profile_sensor_data, callback_group=small
            )
        image_qos = (
            qos_profile_sensor_data if p['image_qos'] == 'sensor_data' else QoSProfile(depth=5)
        )
        if self.array is not None:
            self.create_subscription(
                Float32MultiArray, topics.ARRAY, self._on_array, image_qos, callback_group=images
            )
            if p['array_stamp'] == 'header':
                from .diagnostics import _wall_clock
                from ..stamp_pairing import StampPairer

                self.pairer = StampPairer(
                    p['array_header_tolerance_s'], p['array_header_timeout_s']
                )
                self._pair_drops_seen: dict = {}
                # same callback group as the arrays: the pairer is used from one thread only, and a
                # header and its sample reach their callbacks one after the other (the arrival
                # times the pairing compares)
                self.create_subscription(
                    Header,
                    topics.ARRAY_HEADER,
                    self._on_array_header,
                    image_qos,
                    callback_group=images,
                )
                self.create_timer(
                    0.05, self._expire_array_pairs, callback_group=images, clock=_wall_clock()
                )
            if self.needs_tilt:
                from .diagnostics import _wall_clock

                self.create_timer(
                    0.02, self._drain, callback_group=images, clock=_wall_clock()
                )  # IMU 50+ Hz
        else:
            self.create_subscription(
                CameraInfo,
                topics.CAMERA_INFO,
                self._on_camera_info,
                qos_profile_sensor_data,
                callback_group=small,
            )
            self.create_subscription(
                Image, topics.IMAGE, self._on_image_msg, image_qos, callback_group=images
            )
        self.get_logger().info(
            f'method {self.method}: {t["heading_raw"]} from '
            f'{topics.ARRAY if self.array is not None else topics.IMAGE}'
        )

    # parameters ---------------------------------------------------------------------------------
    def _on_change(self, changed: dict):
        if self.front is None:
            return None
        merged = {**self.params.values, **changed}
        try:
            if {'polarizer_layout', 'pol45_toward'} & set(changed):
                self.front.set_layout(
                    layout_from_text(merged['polarizer_layout']), merged['pol45_toward']
                )
                self.polarizer.count = 0  # check the new convention N frames from now
            if 'demosaic' in changed:
                self.front.demosaic = merged['demosaic']
            if 'sky_check' in changed:
                self.front.sky_check = bool(merged['sky_check'])
            if 'polarizer_check_every' in changed:
                self.polarizer.every_n = int(merged['polarizer_check_every'])
                self.polarizer.count = 0
            if 'use_intensity' in changed:
                self.front.intensity = bool(merged['use_intensity'])
            if {'prior_source', 'prior_max_age_s', 'prior_sigma_deg'} & set(changed):
                self.tilt_prior.prior_source = merged['prior_source']
                self.tilt_prior.prior_max_age_s = float(merged['prior_max_age_s'])
                self.tilt_prior.prior_sigma_deg = float(merged['prior_sigma_deg'])
            if set(SUN_PARAMS) & set(changed):
                self.sun = sun_source(merged)
        except CompassError as exc:
            return str(exc)
        return None

    @property
    def array_input(self) -> bool:
        return self._array_geometry is not None

    def _make_array(self, values: dict):
        from ..photodiode.heading import make_array_estimator

        return make_array_estimator(
            self.method, self._array_geometry, **knob_values(self.method, values, self._knob_specs)
        )

    def _on_knob_change(self, changed: dict):
        if self.front is None:
            return None
        merged = {**self.knob_set.values, **changed}
        if self.array_input:
            try:
                self.array = self._make_array(merged)
            except (CompassError, ValueError) as exc:
                return str(exc)
            return None
        try:
            self.front.set_knobs(knob_values(self.method, merged))
        except (CompassError, ValueError) as exc:
            return str(exc)
        return None

    # inputs -------------------------------------------------------------------------------------
    def _on_camera_info(self, msg):
        """
        Validate camera_info intrinsics; a rejected message withdraws the camera in use.

        Validate intrinsics (:func:`~polarization_compass.bag.decode_camera_info`); a rejected
        message is counted and withdraws the camera in use
        (:class:`~polarization_compass.pipeline.CameraInfoState`). Its stamp also tells of images
        lost on the way (``image_lost``, :class:`ImageLossWatch`).
        """
        try:
            lost = self.loss.camera_info(stamp_ns(msg.header))
        # a header that cannot be read is counted by the decoder below
        except Exception:  # noqa: BLE001
            lost = 0
        for _ in range(lost):
            self.diag.reject(
                'image_lost',
                'a camera_info had no image of its stamp (lost before this node: '
                'middleware queue or transport)',
            )
        try:
            cam = decode_camera_info(msg, self.params['pixel_pitch_um'])
        except MessageError as exc:
            self.diag.reject(f'camera_info_{exc.reason}', str(exc))
            self.camera_info.reject(str(exc))
            return
        self.camera_info.accept(cam)

    @property
    def camera_from_info(self) -> CameraModel | None:
        """Return the accepted camera_info camera, or None (none yet, or rejected)."""
        try:
            return self.camera_info.camera()
        except PipelineError:
            return None

    def _on_imu(self, msg):
        q = self.diag.decoded('imu', decode_orientation, msg)
        if q is not None:
            self.imu.add(stamp_ns(msg.header), q)
            self.attitude_uncertainty.update(msg.orientation_covariance)

    def _on_fix(self, msg):
        site = apply_fix(self.sun, self.diag, msg)
        if site is not None:
            self.site_from_fix = site

    def _fallback_camera_or_none(self) -> CameraModel | None:
        """
        Return the fallback intrinsics at the paper's sensor size for the warm-up.

        For the warm-up: the fallback intrinsics at the paper's sensor size (2448 x 2048, the
        IMX250MZR's and the simulator's), so that the first image of such a camera finds its caches
        built.
        """
        from ..scene import default_scene

        p = self.params
        size = default_scene().camera
        try:
            return CameraModel(
                p['camera_model'],
                int(size.width_px),
                int(size.height_px),
                p['focal_length_mm'],
                p['pixel_pitch_um'],
                p['pixel_pitch_um'],
                max_field_angle_deg=p['max_field_angle_deg'],
            )
        except CameraError:
            return None

    def _camera_for(self, width: int, height: int) -> CameraModel:
        p = self.params
        cam = (
            self.camera_info.camera() if p['camera_info_source'] == 'topic' else None
        )  # raises after a rejection
        if cam is None and p['camera_info_source'] == 'topic':
            self.get_logger().warning(
                f'no camera_info on {topics.CAMERA_INFO} yet: using the fallback intrinsics '
                'from parameters (camera_model, focal_length_mm, pixel_pitch_um)',
                throttle_duration_sec=10.0,
            )
        if cam is None:
            pitch = p['pixel_pitch_um']
            try:
                cam = CameraModel(
                    p['camera_model'],
                    int(width),
                    int(height),
                    p['focal_length_mm'],
                    pitch,
                    pitch,
                    max_field_angle_deg=p['max_field_angle_deg'],
                )
            except CameraError as exc:
                raise PipelineError(f'fallback camera parameters: {exc}') from None
        if (cam.width_px, cam.height_px) != (int(width), int(height)):
            raise PipelineError(
                f'image is {width}x{height} but camera_info says {cam.width_px}x{cam.height_px}'
            )
        return cam

    def _receive_image(self, msg) -> bool:
        """
        Decode and queue one image (the reception thread); a bad one is counted by reason.

        When :data:`MAX_PENDING_IMAGES` wait already, the oldest is dropped and counted
        (``image_queue_full``): a flood never costs a frame without a count. True when queued.
        """
        t_in = self.diag.input()
        try:
            self.loss.image(stamp_ns(msg.header))
        except Exception:  # noqa: BLE001 - the decoder counts a broken header
            pass
        mosaic = self.diag.decoded('', decode_image, msg)
        if mosaic is None:
            return False
        item = (
            stamp_ns(msg.header),
            mosaic,
            int(msg.width),
            int(msg.height),
            t_in,
            time.monotonic() + self.params['imu_max_wait_s'],
            None,
        )
        with self._pending_lock:
            dropped = self.pending.popleft() if len(self.pending) >= MAX_PENDING_IMAGES else None
            self.pending.append(item)
        if dropped is not None:
            self.diag.reject(
                'image_queue_full',
                f'frame {dropped[0] / 1e9:.3f} s dropped: {MAX_PENDING_IMAGES} '
                'images were waiting (processing slower than the image rate)',
            )
        with self._work_cv:
            self._work_cv.notify()
        return True

    def _on_image_msg(self, msg) -> None:
        """Queue an image for the worker thread (started with the first image)."""
        if self._worker is None:
            self._worker = threading.Thread(
                target=self._work, name='heading_estimator_worker', daemon=True
            )
            self._worker.start()
        self._receive_image(msg)

    def _work(self) -> None:
        """
        Run the worker thread: process queued images.

        The worker thread: process queued images; tilt_aware re-checks waiting ones every 20 ms
        (the IMU is 50+ Hz). Any exception is counted, never ends the thread (``_process`` already
        catches them).
        """
        while not self._stop:
            with self._work_cv:
                if not self.pending:
                    self._work_cv.wait(timeout=0.02 if self.needs_tilt else 0.5)
            try:
                self._drain()
            except Exception as exc:  # noqa: BLE001 - the worker must outlive any one frame
                self.diag.reject('estimator_exception', f'{type(exc).__name__}: {exc}')
            if self.needs_tilt and self.pending:
                time.sleep(0.005)  # an image waiting for its IMU sample: do not spin on it

    def destroy_node(self):
        self._stop = True
        cv, worker = (
            getattr(self, '_work_cv', None),
            getattr(self, '_worker', None),
        )  # (a failed __init__)
        if cv is not None:
            with cv:
                cv.notify()
        if worker is not None and worker is not threading.current_thread():
            worker.join(timeout=2.0)
        return super().destroy_node()

    def _on_image(self, msg):
        """Receive and process at once (the synchronous path: tests, direct calls)."""
        if self._receive_image(msg):
            self._drain()

    def _on_array(self, msg):
        """
        Decode a photodiode-array sample, stamp it and queue it like an image.

        A photodiode-array sample: decoded against the geometry, stamped by its paired header (or
        on arrival with array_stamp arrival), then queued like an image.
        """
        arrived_ns = time.monotonic_ns()
        from ..photodiode.readings import array_sample_from_flat, ArrayRecordingError

        t_in = self.diag.input()
        geometry = self.array.geometry

        def decode(m):
            try:
                return array_sample_from_flat(
                    m.data, [d.size for d in m.layout.dim], m.layout.data_offset, geometry
                )
            except ArrayRecordingError as exc:
                raise MessageError('array_layout', str(exc)) from None

        sample = self.diag.decoded('', decode, msg)
        if sample is None:
            if (
                self.pairer is not None
            ):  # it still takes its header with it (never the next sample's)
                self._enqueue_paired(self.pairer.add_array(arrived_ns, arrived_ns / 1e9, None))
            return
        if self.pairer is None:
            t_ns = self.get_clock().now().nanoseconds
            self.pending.append(
                (
                    t_ns,
                    sample,
                    None,
                    None,
                    t_in,
                    time.monotonic() + self.params['imu_max_wait_s'],
                    None,
                )
            )
        else:
            self._enqueue_paired(
                self.pairer.add_array(arrived_ns, arrived_ns / 1e9, (sample, t_in))
            )
        self._drain()

    def _on_array_header(self, msg):
        """Keep the companion header of an array sample (array_stamp header)."""
        arrived_ns = time.monotonic_ns()
        self._enqueue_paired(
            self.pairer.add_header(arrived_ns, arrived_ns / 1e9, stamp_ns(msg.stamp), msg.frame_id)
        )
        self._drain()

    def _expire_array_pairs(self) -> None:
        self.pairer.expire(time.monotonic())
        self._count_pair_drops()

    def _enqueue_paired(self, paired) -> None:
        """
        Queue array samples that found their header; count the pairer's drops.

        Queue array samples that found their header; count the pairer's drops in /diagnostics.
        """
        for s in paired:
            if s.payload is None:  # a sample rejected when decoded: already counted
                continue
            sample, t_in = s.payload
            frame_id = s.frame_id or self.params['frame_id']
            if frame_id.endswith(('_optical_frame', '_optical')):
                self.diag.reject(
                    'array_header_optical_frame',
                    f'header frame_id {frame_id!r} is an optical '
                    'frame (z forward); the heading needs a z-up frame',
                )
                continue
            self.pending.append(
                (
                    s.stamp_ns,
                    sample,
                    None,
                    None,
                    t_in,
                    time.monotonic() + self.params['imu_max_wait_s'],
                    frame_id,
                )
            )
        self._count_pair_drops()

    def _count_pair_drops(self) -> None:
        for reason, n in self.pairer.drops.items():
            for _ in range(n - self._pair_drops_seen.get(reason, 0)):
                self.diag.reject(
                    f'array_{reason}',
                    'array sample without its header'
                    if reason != 'header_without_array'
                    else 'header without its array sample',
                )
            self._pair_drops_seen[reason] = n

    def _drain(self) -> None:
        """
        Process waiting images.

        Process waiting images. tilt_aware needs the IMU at the image's stamp: an image newer than
        the newest IMU sample waits up to imu_max_wait_s (wall) for it, if the IMU stream is live
        (its newest sample within imu_max_wait_s of the image stamp) and fewer than three images
        queue.
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

    def _with_attitude_sigma(self, result, pitch, roll, status: dict):
        """
        Add the IMU tilt's uncertainty to a tilt-reading method's sigma: ``J Sigma_att J^T``.

        ``Sigma_att`` as the ``tilt_corrector``'s (docs/ros.md): the larger of the latest IMU
        message's roll/pitch variances plus ``attitude_sigma_deg``^2, isotropic; ``J`` from the
        method (:meth:`~polarization_compass.estimators.base.Estimator.tilt_sensitivity`).
        """
        if not (self.needs_tilt and result.ok and result.sigma_deg is not None):
            return result
        if pitch is None or roll is None:
            return result
        j = registry.get(self.method).tilt_sensitivity(result, pitch, roll)
        if j is None:
            return result
        s_tilt, known = self.attitude_uncertainty.sigma_deg(
            float(self.params['attitude_sigma_deg']), self.get_logger()
        )
        s_att = math.hypot(j[0] * s_tilt, j[1] * s_tilt)
        status.update(
            attitude_sigma_deg=s_tilt,
            attitude_covariance='imu' if known else 'unknown',
            sigma_attitude_deg=s_att,
        )
        if s_att == 0.0:
            return result
        return dataclasses.replace(
            result,
            sigma_deg=math.hypot(result.sigma_deg, s_att),
            extras={
                **result.extras,
                'sigma_fit_deg': result.sigma_deg,
                'sigma_attitude_deg': s_att,
            },
        )

    def _process(
        self, t_ns: int, mosaic, width: int, height: int, t_in: float, frame_id: str | None = None
    ) -> None:
        p = self.params
        status = {'stamp_ns': t_ns, 'method': self.method}
        try:
            camera = self._camera_for(width, height) if self.array is None else None
            if p['site_source'] == 'navsatfix' and self.site_from_fix is None:
                raise PipelineError('no NavSatFix received yet (site_source navsatfix)')
            if p['time_source'] == 'stamp':
                sun_az, sun_alt = self.sun.at_ns(t_ns)
            else:
                if not p['time_utc']:
                    raise PipelineError('time_source is parameter but time_utc is empty')
                from ..bag import ns_from_utc
                from ..scene import parse_time_utc

                sun_az, sun_alt = self.sun.at_ns(ns_from_utc(parse_time_utc(p['time_utc'])))
            inp = self.tilt_prior.inputs(
                t_ns, *self.tilt_prior.lookups(self.imu, t_ns, int(p['imu_tolerance_s'] * 1e9))
            )
            if inp.tilt_missing:
                raise PipelineError(
                    f'no IMU sample within {p["imu_tolerance_s"]:g} s of the image stamp '
                    f'(newest IMU stamp: {self._newest_imu_text()})'
                )
            pitch, roll, prior = inp.pitch_deg, inp.roll_deg, inp.prior_bearing_deg
            t0 = time.perf_counter()
            if self.array is not None:
                result = self._estimate_array(mosaic, sun_az, sun_alt, pitch, roll, prior)
            else:
                result = self.front.estimate(mosaic, camera, sun_az, sun_alt, pitch, roll, prior)
                result = self._with_attitude_sigma(result, pitch, roll, status)
            result = self.tilt_prior.checked(
                result, inp
            )  # heading vs. the IMU prior (a named step)
            status['estimate_ms'] = round((time.perf_counter() - t0) * 1e3, 3)
            if self.array is None:
                self._check_polarizer(mosaic, camera, sun_alt, pitch, roll, status)
        except (PipelineError, CompassError) as exc:
            self.get_logger().warning(
                f'frame {t_ns / 1e9:.3f} s: {exc}', throttle_duration_sec=5.0
            )
            status.update(status='bad_input', reason=str(exc), ok=False, published=False)
            self._publish_status(status)
            self.diag.done(t_in, t_ns, f'bad_input: {exc}', ok=False)
            return
        except Exception as exc:  # noqa: BLE001 - one bad frame must not stop the node
            self.diag.reject('estimator_exception', f'{type(exc).__name__}: {exc}')
            status.update(
                status='estimator_exception',
                reason=f'{type(exc).__name__}: {exc}',
                ok=False,
                published=False,
            )
            self._publish_status(status)
            return
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
            prior_bearing_deg=prior,
            resolved_by=result.extras.get('ambiguity_resolved_by'),
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

    def _estimate_array(self, sample, sun_az, sun_alt, pitch, roll, prior):
        from ..photodiode.heading import estimate_recording

        return estimate_recording(self.array, sample[None], sun_az, sun_alt, pitch, roll, prior)[0]

    def _check_polarizer(self, mosaic, camera, sun_alt, pitch, roll, status: dict) -> None:
        """
        Check every ``polarizer_check_every``-th image against the polarizer convention.

        Every polarizer_check_every-th image: does the sky support the configured polarizer
        convention? A contradiction is a diagnostics ERROR naming the fix (until a later check
        supports the configuration); a failing check is logged and never stops the frame.
        """
        had_error = self.polarizer.error
        try:
            t0 = time.perf_counter()
            rep = self.polarizer.feed(mosaic, camera, self.front.layout, sun_alt, pitch, roll)
        except Exception as exc:  # noqa: BLE001 - a diagnostic, never fatal
            self.get_logger().warning(
                f'polarizer check failed: {type(exc).__name__}: {exc}', throttle_duration_sec=30.0
            )
            return
        if rep is None:
            return
        status['polarizer_check'] = {
            'verdict': rep['verdict'],
            'margin': rep.get('margin'),
            'ms': round((time.perf_counter() - t0) * 1e3, 1),
        }
        if self.polarizer.error:
            self.get_logger().error(self.polarizer.error, throttle_duration_sec=60.0)
            self.diag.set_error(self.polarizer.error)
        elif had_error and self.diag.error == had_error:
            self.diag.set_error(None)

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


def main(argv=None) -> int:
    return run_node(HeadingEstimatorNode, 'heading_estimator', argv)


if __name__ == '__main__':
    raise SystemExit(main())
