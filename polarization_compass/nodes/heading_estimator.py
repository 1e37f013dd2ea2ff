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
``publish_ambiguous`` is true; their status says so. A photodiode-array compass has its own node,
``array_heading_estimator``; the sun, IMU, queue and outputs both share are
:class:`~.heading_node.HeadingNodeBase`'s.
"""

from __future__ import annotations

import threading
import time

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.qos import qos_profile_sensor_data, QoSProfile
from sensor_msgs.msg import CameraInfo, Image

from .heading_node import HeadingNodeBase
from .msgs import decode_image
from .rosparams import ParameterSet
from .runner import run_node
from ..bag import decode_camera_info, MessageError, stamp_ns
from ..camera import CameraError, CameraModel
from ..errors import CompassError
from ..mount import Mount
from ..pipeline import (
    apply_rules,
    CameraInfoState,
    HeadingFrontEnd,
    ImageLossWatch,
    PipelineError,
    PolarizerMonitor,
    SensorReadout,
    warm_up,
)
from ..pipeline.attitude_sigma import AttitudeUncertainty
from ..specs import topics
from ..specs.params import ESTIMATOR, knob_params, knob_values, layout_from_text

__all__ = ['HeadingEstimatorNode', 'main', 'MAX_PENDING_IMAGES']

#: Decoded images waiting to be processed; beyond, the oldest is dropped and counted
#: (image_queue_full).
MAX_PENDING_IMAGES = 8


class HeadingEstimatorNode(HeadingNodeBase):
    """The ``heading_estimator`` node (see the module docstring)."""

    INPUT_NAME = 'image'

    def __init__(self, **kwargs):
        super().__init__('heading_estimator', **kwargs)
        self.front = None
        self.params = ParameterSet(self, ESTIMATOR, on_change=self._on_change)
        self.method = self.params['method']
        p = self.params
        self._make_front_end()
        self.camera_info = CameraInfoState()  # validated intrinsics from camera_info, or why not
        self.loss = ImageLossWatch()  # images that never arrived (camera_info without its image)
        self.attitude_uncertainty = AttitudeUncertainty()  # the latest IMU's tilt variance
        self._make_diagnostics(f'heading estimator ({self.method})')
        self.polarizer = PolarizerMonitor(p['polarizer_check_every'])
        # a mirrored readout (readout_flip): images read back as the sensor sees them, K mirrored
        self.readout = SensorReadout(p['readout_flip'])
        # Images are received (decoded and queued) in the executor and processed in this node's own
        # worker thread (:meth:`_work`), whatever the executor (the default EventsExecutor is
        # single-threaded): a long estimate never blocks reception, so the middleware's 5-deep
        # image queue does not overflow silently under a flood; our queue (MAX_PENDING_IMAGES)
        # drops the oldest image when full and counts it (rejected.image_queue_full in
        # /diagnostics). With the Python executors, two threads: images in one group, the small
        # inputs (IMU, camera_info, fix) in another.
        # (image_qos replay: a played bag's images queue here, none dropped below that depth)
        self.max_pending = (
            topics.REPLAY_IMAGE_DEPTH if p['image_qos'] == 'replay' else MAX_PENDING_IMAGES
        )
        self.executor_threads = 2
        small, images = MutuallyExclusiveCallbackGroup(), MutuallyExclusiveCallbackGroup()
        self._work_cv = threading.Condition()
        self._worker = None
        self._stop = False
        self._start_common(p, small)
        self.imu.mount = Mount(p['mount_pitch_deg'], p['mount_roll_deg'])  # camera_tilt composes
        self._subscribe_camera(small, images)
        self.get_logger().info(
            f'method {self.method}: {topics.method_topics(self.method)["heading_raw"]} from '
            f'{topics.IMAGE}'
        )

    def _make_front_end(self) -> None:
        """Declare the method's knobs and build the front end; warm its kernels up."""
        p = self.params
        try:
            knobs = knob_params(self.method)
        except CompassError as exc:
            raise CompassError(f'method {self.method!r}: {exc}') from None
        self.knob_set = ParameterSet(self, knobs, on_change=self._on_knob_change)
        self.front = HeadingFrontEnd(
            self.method,
            knob_values(self.method, self.knob_set.values),
            layout_from_text(p['polarizer_layout']),
            p['pol45_toward'],
            p['demosaic'],
            p['use_intensity'],
            p['sky_check'],
            p['principal_point_sigma_px'],
        )
        self._warm_up(lambda: warm_up(self.front, camera=self._fallback_camera_or_none()), 'image')

    def _subscribe_camera(self, small, images) -> None:
        """Subscribe to camera_info (small inputs) and the images."""
        p = self.params
        image_qos = {
            'sensor_data': qos_profile_sensor_data,
            'reliable': QoSProfile(depth=5),
            # a played bag (the player publishes reliably): queue, never drop, behind a slow node
            'replay': QoSProfile(depth=topics.REPLAY_IMAGE_DEPTH),
        }[p['image_qos']]
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
                self.polarizer.reset()  # check the new convention from the next image on
            if 'demosaic' in changed:
                self.front.demosaic = merged['demosaic']
            if 'sky_check' in changed:
                self.front.sky_check = bool(merged['sky_check'])
            if 'polarizer_check_every' in changed:
                self.polarizer.every_n = int(merged['polarizer_check_every'])
                self.polarizer.reset()
            if 'use_intensity' in changed:
                self.front.intensity = bool(merged['use_intensity'])
            self._update_common(changed, merged)
        except CompassError as exc:
            return str(exc)
        return None

    def _on_knob_change(self, changed: dict):
        if self.front is None:
            return None
        merged = {**self.knob_set.values, **changed}
        try:
            self.front.set_knobs(knob_values(self.method, merged))
        except (CompassError, ValueError) as exc:
            return str(exc)
        return None

    # inputs -------------------------------------------------------------------------------------
    def _on_camera_info(self, msg):
        """
        Validate camera_info intrinsics; a rejected message withdraws the camera in use.

        The intrinsics are checked by :func:`~polarization_compass.bag.decode_camera_info`; a
        rejected message is counted and withdraws the camera in use
        (:class:`~polarization_compass.pipeline.CameraInfoState`). Its stamp also tells of images
        lost on the way (``image_lost``, :class:`ImageLossWatch`).
        """
        try:
            stamp = stamp_ns(msg.header)
            lost = self.loss.camera_info(stamp)
        # a header that cannot be read is counted by the decoder below
        except Exception:  # noqa: BLE001
            stamp, lost = None, 0
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
            self.camera_info.reject(str(exc), stamp)
            return
        self.camera_info.accept(cam, stamp)

    def _on_imu_extra(self, msg) -> None:
        """Keep the latest IMU's tilt variance (tilt_aware's attitude sigma)."""
        self.attitude_uncertainty.update(msg.orientation_covariance)

    def _fallback_camera_or_none(self) -> CameraModel | None:
        """
        Return the fallback intrinsics at the paper's sensor size for the warm-up.

        The size is 2448 x 2048 (the IMX250MZR's and the simulator's), so that the first image of
        such a camera finds its caches built.
        """
        from ..scene_load import default_scene

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

    def _camera_for(self, width: int, height: int, t_ns: int | None = None) -> CameraModel:
        p = self.params
        cam = (
            self.camera_info.camera(t_ns) if p['camera_info_source'] == 'topic' else None
        )  # the image's own camera_info (by stamp), else the latest; raises after a rejection
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
        return self.readout.camera(cam)  # the sensor's own image's (readout_flip)

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
        t_ns = stamp_ns(msg.header)
        why = self._size_mismatch(t_ns, int(msg.width), int(msg.height))
        if why is not None:  # its bad_input status now: queued, it would evict a good frame
            self._publish_status(
                {
                    'stamp_ns': t_ns,
                    'method': self.method,
                    'status': 'bad_input',
                    'reason': why,
                    'ok': False,
                    'published': False,
                }
            )
            self.diag.done(t_in, t_ns, f'bad_input: {why}', ok=False)
            return False
        mosaic = self.readout.image(mosaic)  # read as the sensor sees it (readout_flip)
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
            dropped = self.pending.popleft() if len(self.pending) >= self.max_pending else None
            self.pending.append(item)
        if dropped is not None:
            self.diag.reject(
                'image_queue_full',
                f'frame {dropped[0] / 1e9:.3f} s dropped: {self.max_pending} '
                'images were waiting (processing slower than the image rate)',
            )
        with self._work_cv:
            self._work_cv.notify()
        return True

    def _size_mismatch(self, t_ns: int, width: int, height: int) -> str | None:
        """
        Say why an image cannot match the camera_info it will be paired with, or None.

        Checked on reception, before the image is queued (its ``bad_input`` status is published at
        once): a burst of well-formed images of another size used to fill the worker's queue and
        push out the good frames waiting there (``image_queue_full``), only to fail one by one in
        the worker. The camera is the image's
        own camera_info (by stamp), else the latest; none yet, or a rejected one: the worker
        decides as before.
        """
        if self.params['camera_info_source'] != 'topic':
            return None
        try:
            cam = self.camera_info.camera(t_ns)
        except PipelineError:
            return None
        if cam is None or (cam.width_px, cam.height_px) == (width, height):
            return None
        return f'image is {width}x{height} but camera_info says {cam.width_px}x{cam.height_px}'

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

        tilt_aware re-checks waiting ones every 20 ms (the IMU is 50+ Hz). Any exception is
        counted, never ends the thread (``_process`` already catches them).
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

    def _prepare(self, mosaic, width, height, t_ns=None) -> CameraModel:
        """Return the camera of an image of this size and stamp (camera_info or the fallback)."""
        return self._camera_for(width, height, t_ns)

    def _estimate(self, camera, mosaic, sun_az, sun_alt, inp, status: dict):
        """Return the heading of one image: the front end, then the IMU tilt's uncertainty."""
        pitch, roll = inp.pitch_deg, inp.roll_deg
        result = self.front.estimate(
            mosaic, camera, sun_az, sun_alt, pitch, roll, inp.prior_bearing_deg
        )
        self._check_polarizer(mosaic, camera, sun_alt, pitch, roll, status)
        # the IMU tilt's share of the sigma (Sigma_att: the latest IMU's covariance plus
        # attitude_sigma_deg), the polarizer gate, the heading vs. the IMU prior: replay applies
        # the same rules
        tilt_sigma = (
            self.attitude_uncertainty.sigma_deg(
                float(self.params['attitude_sigma_deg']), self.get_logger()
            )
            if self.needs_tilt
            else None
        )
        return apply_rules(result, inp, self.tilt_prior, self.polarizer, tilt_sigma, status)

    def _debug_rgb(self, camera, mosaic, result, sun, inp):
        """Render the diagnostic figure of one image (~/debug_image; the estimate's layers)."""
        from ..diagnostic_rgb import quick_rgb
        from ..pipeline.sun import Sun
        from ..sky_view import view_from_mosaic

        layout = self.front.layout
        view = view_from_mosaic(
            mosaic,
            camera,
            Sun(sun[0], sun[1], 'node'),
            [result],
            layout.angles_deg,
            layout.pol45_toward,
            self.front.demosaic,
            inp.pitch_deg,
            inp.roll_deg,
            max_side_px=256,
            sampled=True,
            label=f'heading_estimator ({self.method})',
        )
        return quick_rgb(view, int(self.params['debug_width_px']))

    def _check_polarizer(self, mosaic, camera, sun_alt, pitch, roll, status: dict) -> None:
        """
        Check the image against the polarizer convention when the monitor says it is due.

        Every image until the sky supports the configuration, then every
        ``polarizer_check_every``-th (:class:`PolarizerMonitor`). A contradiction is a diagnostics
        ERROR naming the fix (until a later check supports the configuration) and the results are
        gated (:func:`apply_rules`); a failing check is logged and never stops the frame.
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


def main(argv=None) -> int:
    return run_node(HeadingEstimatorNode, 'heading_estimator', argv)


if __name__ == '__main__':
    raise SystemExit(main())
