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
``record-sim``: a synthetic field run written as a real rig records it with ``ros2 bag record``.

What is in the bag (topics of the default mapping,
:data:`~polarization_compass.bag.BUILTIN_TOPIC_MAP`):

``/camera/image_raw``      sensor_msgs/Image ``mono16`` (12-bit samples) or ``mono8``: the raw 2 x
                           2 polarizer mosaic of the whole sensor, rendered and passed through the
                           scene's sensor effects (the same renderer + ``sensor.simulate_mosaic``
                           as the ``sky_simulator`` node); frame_id ``camera_optical_frame``.
``/camera/camera_info``    with every image, as drivers do (K of the raw mosaic, no distortion).
``/imu/data``              sensor_msgs/Imu, ``imu_rate_hz``: body attitude in ENU with white noise
                           on roll/pitch, a biased noisy yaw (a magnetometer-grade yaw: only a
                           prior), and REP-145 covariances; frame_id ``base_link``.
``/ground_truth/heading``  the reference heading as a dual-antenna GNSS gives it, in the form the
                           estimator publishes and robot_localization fuses: sensor_msgs/Imu with a
                           pure REP-103 yaw quaternion, yaw variance = noise^2, large roll/pitch
                           variances; frame_id ``base_link``. Stamped with the image stamps (camera
                           triggered by the receiver's PPS) unless ``reference_rate_hz`` gives the
                           receiver its own epochs.
``/gps/fix``               sensor_msgs/NavSatFix of the scene's site, 1 Hz.

Receive (log) times are the stamps plus a transport latency with jitter, so they differ from the
header stamps as in a real recording. The motion is the simulator's profile
(:class:`~polarization_compass.motion.MotionProfile`): one full turn over the run at a fixed
tilt, like the paper's Fig 17 (pitch -20 deg), starting at the scene's bearing and time.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from pathlib import Path

import numpy as np

from .bag import (
    BagWriter,
    default_topic_map,
    encode_camera_info,
    encode_imu,
    encode_mosaic,
    encode_navsatfix,
    ns_from_utc,
    TopicMap,
)
from .conventions import matrix_to_quat, R_enu_body_from_camera_attitude, yaw_enu_quaternion
from .errors import CompassError

__all__ = ['RecordSpec', 'record_sim', 'FIG17_PITCH_DEG']

#: The paper's Fig 17 run: a full turn with the camera pitched by -20 deg.
FIG17_PITCH_DEG = -20.0


@dataclass(frozen=True)
class RecordSpec:
    """
    Describe what to record. Angles in degrees, rates in Hz, times in seconds.

    Parameters
    ----------
    duration_s : float
        Length of the run [s], in (0, 86400].
    rate_hz : float, default 10
        Image rate [Hz].
    storage : {"mcap", "sqlite3"}, default "mcap"
        rosbag2 storage plugin.
    encoding : {"mono16", "mono8"}, default "mono16"
        Image encoding of the raw mosaics.
    pitch_deg, roll_deg : float, optional
        Camera pitch and roll [deg] (eq 21), in [-60, 60]; None: the scene's attitude if it is
        tilted, else Fig 17's run (pitch -20, roll 0).
    turns : float, default 1
        Turns during the run (sign: direction).
    imu_rate_hz : float, default 50
        IMU rate [Hz].
    imu_attitude_noise_deg, imu_yaw_noise_deg, imu_yaw_bias_deg : float
        IMU roll/pitch noise, yaw noise (1 sigma) and yaw bias [deg].
    reference_noise_deg : float, default 0.1
        Noise of the reference heading [deg], 1 sigma.
    reference_rate_hz : float, optional
        Reference heading rate [Hz]; None: stamped with the image stamps.
    fix_rate_hz : float, default 1
        NavSatFix rate [Hz].
    seed : int, default 0
        Seed of the latencies, IMU and reference noise.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 21 (pitch alpha, roll
       beta) and Fig 17 (a full turn at pitch -20 deg).

    """

    duration_s: float
    rate_hz: float = 10.0
    storage: str = 'mcap'
    encoding: str = 'mono16'
    pitch_deg: float | None = None
    roll_deg: float | None = None
    turns: float = 1.0
    imu_rate_hz: float = 50.0
    imu_attitude_noise_deg: float = 0.05
    imu_yaw_noise_deg: float = 2.0
    imu_yaw_bias_deg: float = 5.0
    reference_noise_deg: float = 0.1
    reference_rate_hz: float | None = None
    fix_rate_hz: float = 1.0
    seed: int = 0

    def check(self) -> None:
        """
        Check every field's range and choice.

        Raises
        ------
        CompassError
            A field is non-finite or out of range (the message names it and the range), an unknown
            storage or encoding, or a run too short to hold one frame.

        """

        def rng_(name, v, lo, hi, lo_open=False):
            if v is None:
                return
            ok = (
                isinstance(v, (int, float))
                and math.isfinite(v)
                and (lo < v if lo_open else lo <= v)
                and v <= hi
            )
            if not ok:
                raise CompassError(
                    f'{name} must be finite and in {"(" if lo_open else "["}{lo}, {hi}], got {v!r}'
                )

        rng_('duration', self.duration_s, 0.0, 86400.0, lo_open=True)
        rng_('rate', self.rate_hz, 0.0, 1000.0, lo_open=True)
        rng_('pitch', self.pitch_deg, -60.0, 60.0)
        rng_('roll', self.roll_deg, -60.0, 60.0)
        rng_('turns', self.turns, -100.0, 100.0)
        rng_('imu rate', self.imu_rate_hz, 0.0, 2000.0, lo_open=True)
        rng_('imu attitude noise', self.imu_attitude_noise_deg, 0.0, 30.0)
        rng_('imu yaw noise', self.imu_yaw_noise_deg, 0.0, 90.0)
        rng_('imu yaw bias', self.imu_yaw_bias_deg, -90.0, 90.0)
        rng_('reference noise', self.reference_noise_deg, 0.0, 30.0)
        rng_('reference rate', self.reference_rate_hz, 0.0, 1000.0, lo_open=True)
        rng_('fix rate', self.fix_rate_hz, 0.0, 100.0, lo_open=True)
        if self.storage not in ('mcap', 'sqlite3'):
            raise CompassError(f'storage must be mcap or sqlite3, got {self.storage!r}')
        if self.encoding not in ('mono16', 'mono8'):
            raise CompassError(f'encoding must be mono16 or mono8, got {self.encoding!r}')
        if self.duration_s * self.rate_hz < 1:
            raise CompassError(f'a {self.duration_s:g} s run at {self.rate_hz:g} Hz has no frame')


def _latency_ns(rng, mean_ms: float, jitter_ms: float) -> int:
    return int(round((mean_ms + jitter_ms * float(rng.random())) * 1e6))


def record_sim(
    scene, spec: RecordSpec, out, topic_map: TopicMap | None = None, progress=None
) -> dict:
    """
    Render ``spec.duration_s`` of a field run of ``scene`` into the rosbag2 ``out``.

    Images (raw mosaics), IMU, reference heading and NavSatFix, with the latencies and noise of
    ``spec``; the motion is a :class:`~polarization_compass.motion.MotionProfile`.

    Parameters
    ----------
    scene : Scene
        The scene (site, time, sky, camera, sensor); its sun must come from an ephemeris.
    spec : RecordSpec
        What to record (checked first).
    out : str or os.PathLike
        The bag directory to write.
    topic_map : TopicMap, optional
        Topic names and types; default :func:`default_topic_map`.
    progress : callable, optional
        ``progress(frames_done, frames_total)`` after each image.

    Returns
    -------
    dict
        ``bag``, ``storage``, ``frames``, ``start_ns`` [ns], ``duration_s`` [s], ``pitch_deg``,
        ``roll_deg``, ``turn_rate_deg_s`` [deg/s], ``messages`` ({topic: count}), ``truth``
        ({image stamp_ns: true bearing_deg}), ``camera`` (``"WxH"``), ``encoding`` and ``sensor``.

    Raises
    ------
    CompassError
        A bad ``spec`` (see :meth:`RecordSpec.check`), or a scene with a fixed sun.

    """
    spec.check()
    if scene.sun_fixed is not None:
        raise CompassError(
            "record-sim needs the sun from an ephemeris (the bag's stamps and NavSatFix "
            'decide it on replay): remove sun.azimuth_deg/altitude_deg from the scene'
        )
    tm = topic_map or default_topic_map()
    out = Path(out)
    profile = _motion_profile(scene, spec)
    start_ns = ns_from_utc(scene.time_utc)
    rng = np.random.default_rng([spec.seed, 1])  # latencies, IMU and reference noise
    events, frame_stamps = _schedule(spec, start_ns, profile.total_s(), rng)
    rec = _Recorder(scene, spec, profile, start_ns, rng)
    with BagWriter(out, tm, storage=spec.storage) as w:
        for log_ns, _, role, t, k in events:
            rec.write(w, role, t, k, log_ns)
            if role == 'image' and progress is not None:
                progress(len(rec.truth), len(frame_stamps))
        counts = dict(w.counts)
    return {
        'bag': str(out),
        'storage': spec.storage,
        'frames': len(frame_stamps),
        'start_ns': start_ns,
        'duration_s': spec.duration_s,
        'pitch_deg': profile.pitch_deg,
        'roll_deg': profile.roll_deg,
        'turn_rate_deg_s': profile.turn_rate_deg_s,
        'messages': {tm.spec(r).topic: n for r, n in counts.items()},
        'truth': rec.truth,
        'camera': f'{scene.camera.width_px}x{scene.camera.height_px}',
        'encoding': spec.encoding,
        'sensor': rec.sensor_cfg.describe(),
    }


def _motion_profile(scene, spec: RecordSpec):
    """Return the run's motion: the scene's bearing, turning, at the spec's or scene's tilt."""
    from .motion import MotionProfile

    a = scene.attitude
    tilted = abs(a.pitch_deg) > 0 or abs(a.roll_deg) > 0
    pitch = (
        spec.pitch_deg
        if spec.pitch_deg is not None
        else (a.pitch_deg if tilted else FIG17_PITCH_DEG)
    )
    roll = spec.roll_deg if spec.roll_deg is not None else (a.roll_deg if tilted else 0.0)
    return MotionProfile(
        start_bearing_deg=a.bearing_deg,
        turn_rate_deg_s=360.0 * spec.turns / spec.duration_s,
        pitch_deg=pitch,
        roll_deg=roll,
        turns=0.0,
        duration_s=spec.duration_s,
    )


def _schedule(spec: RecordSpec, start_ns: int, total_s: float, rng):
    """
    List every message with its receive time, sorted; images are rendered when their turn comes.

    Returns (events, frame stamps [ns]); an event is (receive ns, order, role, stamp ns, index).
    Draws the latencies from ``rng`` in a fixed order (frames, then each receiver).
    """
    from .motion import frame_times_ns

    events = []
    k = 0
    frame_stamps = []
    while True:
        t = frame_times_ns(start_ns, spec.rate_hz, total_s, k)
        if t is None:
            break
        frame_stamps.append(t)
        lat = _latency_ns(rng, 25.0, 10.0)
        events.append((t + lat, 0, 'camera_info', t, k))
        events.append((t + lat + 1000, 1, 'image', t, k))
        if spec.reference_rate_hz is None:
            events.append((t + _latency_ns(rng, 40.0, 20.0), 2, 'reference', t, k))
        k += 1
    end_ns = frame_stamps[-1]
    for rate, role, mean_ms, jit_ms in (
        (spec.imu_rate_hz, 'imu', 2.0, 1.0),
        (spec.fix_rate_hz, 'navsatfix', 60.0, 40.0),
        (spec.reference_rate_hz, 'reference', 40.0, 20.0),
    ):
        if rate is None or role == 'reference' and spec.reference_rate_hz is None:
            continue
        # receivers tick on their own epochs (multiples of 1/rate since the epoch), covering the
        # run
        period = 1e9 / rate
        j0 = math.floor(start_ns / period) - 1
        j1 = math.ceil(end_ns / period) + 1
        for j in range(j0, j1 + 1):
            t = int(round(j * period))
            events.append((t + _latency_ns(rng, mean_ms, jit_ms), 3, role, t, j))
    events.sort()
    return events, frame_stamps


class _Recorder:
    """Encode each scheduled message of the run; images rendered with their own noise stream."""

    def __init__(self, scene, spec: RecordSpec, profile, start_ns: int, rng):
        from .camera_pixels import PixelSelection
        from .pipeline import SunSource
        from .render import Renderer
        from .sensor import sensor_config_for_encoding

        self.scene, self.spec, self.profile, self.start_ns, self.rng = (
            scene,
            spec,
            profile,
            start_ns,
            rng,
        )
        self.sensor_cfg = sensor_config_for_encoding(scene.sensor, spec.encoding)
        self.renderer = Renderer(scene.replace(sensor={}), pixels=PixelSelection.full())
        site = scene.site
        self.sun = SunSource(
            site.latitude_deg, site.longitude_deg, site.altitude_m, scene.sun_model
        )
        self.truth = {}  # image stamp_ns: true bearing_deg

    def write(self, w, role: str, t: int, k: int, log_ns: int) -> None:
        """Write the ``role`` message stamped ``t`` (the ``k``-th of its stream) at ``log_ns``."""
        att = self.profile.attitude((t - self.start_ns) / 1e9)
        R_enu_body = R_enu_body_from_camera_attitude(att)
        if role == 'camera_info':
            msg = encode_camera_info(self.scene.camera, t, 'camera_optical_frame')
        elif role == 'image':
            msg = self._image(att, t, k)
        elif role == 'imu':
            msg = self._imu(R_enu_body, t)
        elif role == 'reference':
            msg = self._reference(R_enu_body, t)
        else:  # navsatfix
            site = self.scene.site
            msg = encode_navsatfix(
                site.latitude_deg, site.longitude_deg, site.altitude_m, t, 'gps'
            )
        w.write(role, msg, log_ns)

    def _image(self, att, t: int, k: int):
        """Render and encode the raw mosaic of image ``k`` (noise seeded by the spec and ``k``)."""
        from .render import SunDirection
        from .sensor import simulate_mosaic

        az, alt = self.sun.at_ns(t)
        frame = self.renderer.render(attitude=att, sun=SunDirection(az, alt))
        cfg = self.sensor_cfg
        mosaic = simulate_mosaic(
            frame.aop_rad,
            frame.dop,
            frame.intensity,
            cfg,
            cfg.layout,
            np.random.default_rng([self.spec.seed, 2, k]),
        )
        self.truth[t] = float(att.bearing_deg)
        return encode_mosaic(mosaic, t, 'camera_optical_frame')

    def _imu(self, R_enu_body, t: int):
        """Encode an IMU reading: the attitude with roll/pitch and yaw noise and bias."""
        from .motion import imu_reading

        spec = self.spec
        R, variances = imu_reading(
            R_enu_body,
            self.rng.standard_normal(3),
            spec.imu_attitude_noise_deg,
            spec.imu_yaw_noise_deg,
            spec.imu_yaw_bias_deg,
        )
        return encode_imu(matrix_to_quat(R), t, 'base_link', variances)

    def _reference(self, R_enu_body, t: int):
        """Encode the reference heading (dual-antenna GNSS form): the true yaw plus noise."""
        noise_deg = self.spec.reference_noise_deg
        yaw_enu = math.atan2(R_enu_body[1, 0], R_enu_body[0, 0])
        yaw_enu += math.radians(noise_deg * float(self.rng.standard_normal()))
        var_y = max(math.radians(noise_deg) ** 2, 1e-12)
        return encode_imu(yaw_enu_quaternion(yaw_enu), t, 'base_link', (1e3, 1e3, var_y))
