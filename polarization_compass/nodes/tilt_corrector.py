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
``tilt_corrector``: removes the tilt error of a classical method's heading with an error map.

Subscribes to ``compass/<method>/heading_raw`` (sensor_msgs/Imu from heading_estimator),
``imu/data`` (body attitude in ENU; best effort, so that reliable and best-effort IMU drivers both
connect) and, with ``site_source: navsatfix``, ``gps/fix`` (sensor_msgs/NavSatFix: the site, as
heading_estimator takes it). Each heading is paired with the IMU at its stamp: interpolated between
the samples either side when both are within ``imu_tolerance_s``, else the nearer one within it. A
heading whose stamp is newer than the newest IMU sample waits up to ``imu_max_wait_s`` (wall) for
the IMU to catch up; when nothing is within tolerance the heading is reported (status ``stale_imu``
/ ``no_imu``, counted in /diagnostics) and not published: a tilt is never guessed.

The camera's pitch and roll (eq 21) follow from the IMU attitude and the mounting (``R_enu_cam =
R_enu_body @ R_body_cam``); the sun's altitude and azimuth from the stamp and the site (the
parameters, or the latest NavSatFix: until the first fix a heading that needs the sun gets status
``no_fix`` and is not published). ``correction: error_map`` inverts ``psi_meas = psi + e(psi, h,
pitch, roll)`` with :class:`polarization_compass.correction.TiltCorrector` (status out_of_domain,
no_solution, multiple_solutions: reported, not published); ``none`` passes the heading through.

Publishes ``compass/<method>/heading`` (Imu, robot_localization form, yaw variance = raw variance +
``correction_sigma_deg``^2 + the attitude's share ``J Sigma_att J^T``),
``compass/<method>/bearing_deg`` (Float64), ``.../correction_status`` (String, JSON per heading)
and /diagnostics.

Attitude uncertainty: the corrected heading moves with the pitch and roll it was corrected at,
by ``J = d psi / d(pitch, roll)``
(:meth:`~polarization_compass.correction.TiltCorrector.heading_sensitivity`). ``Sigma_att`` is
isotropic: the larger of the latest IMU message's roll and pitch variances
(``orientation_covariance[0]`` and ``[4]``, body axes; the larger bounds the camera's pitch and
roll whatever the mounting) plus ``attitude_sigma_deg``^2 (what the IMU cannot know: boresight,
time offset). An all-zero covariance means "unknown" (sensor_msgs/Imu): then only
``attitude_sigma_deg`` is propagated, and with it 0 nothing is (logged once, ``attitude_covariance:
unknown`` in the status).
"""

from __future__ import annotations

from collections import deque
import json
import math
from pathlib import Path

from rclpy.node import Node
from rclpy.qos import (
    qos_profile_sensor_data,
    qos_profile_system_default,
    QoSProfile,
    ReliabilityPolicy,
)
from sensor_msgs.msg import Imu, NavSatFix
from std_msgs.msg import Float64, String

from .diagnostics import _wall_clock, Diagnostics
from .msgs import heading_from_imu, heading_imu
from .rosparams import ParameterSet
from .runner import run_node
from ..bag import decode_orientation, stamp_ns
from ..errors import CompassError
from ..mount import Mount
from ..pipeline import AttitudeBuffer
from ..pipeline.attitude_sigma import AttitudeUncertainty
from ..specs import topics
from ..specs.params import apply_fix, CORRECTOR, SUN_PARAMS, sun_source

__all__ = ['TiltCorrectorNode', 'main', 'load_corrector', 'MAP_HELP']

MAP_HELP = (
    'generate one with: polarization-compass errormap --methods {method} --sun-altitude 0:50:5 '
    '--yaw -180:175:5 --pitch -30:30:5 --roll -30:30:5 --out {path} (polarization-compass sim '
    'makes a '
    'small one for its scenario), or set correction:=none'
)


def load_corrector(path: str, method: str):
    """
    Return the TiltCorrector for ``method`` from ``path``.

    An empty ``path`` ("") takes the map shipped with the package.

    Raises CompassError naming the file and how to make one when it is missing or unusable.
    """
    from ..correction import default_map_path, TiltCorrector
    from ..errormap import ErrorMapError

    p = Path(path) if path else default_map_path()
    if not p.exists():  # a file (.npz, NetCDF) or a Zarr store directory
        raise CompassError(
            f'error map {str(p)!r} does not exist: ' + MAP_HELP.format(method=method, path=p)
        )
    try:
        return TiltCorrector.from_file(p, method)
    except ErrorMapError as exc:
        raise CompassError(
            f'error map {str(p)!r}: {exc}; ' + MAP_HELP.format(method=method, path=p)
        ) from None
    except (
        RecursionError,
        MemoryError,
    ) as exc:  # belt and braces: the loader bounds what it reads
        raise CompassError(
            f'error map {str(p)!r}: cannot be read ({type(exc).__name__}); '
            + MAP_HELP.format(method=method, path=p)
        ) from None


class TiltCorrectorNode(Node):
    """The ``tilt_corrector`` node (see the module docstring)."""

    def __init__(self, **kwargs):
        super().__init__('tilt_corrector', **kwargs)
        self.corrector = None
        self.params = ParameterSet(self, CORRECTOR, on_change=self._on_change)
        p = self.params
        self.method = p['method']
        if p['correction'] == 'error_map':
            self.corrector = load_corrector(p['error_map'], self.method)
        self.sun = sun_source(p)
        self.site_from_fix = (
            None  # (lat, lon, alt) of the latest usable NavSatFix (site_source navsatfix)
        )
        self.imu = AttitudeBuffer(keep_ns=int(p['imu_buffer_s'] * 1e9))
        self.imu.mount = Mount(p['mount_pitch_deg'], p['mount_roll_deg'])  # camera_tilt composes
        self.attitude_uncertainty = AttitudeUncertainty()  # the latest IMU's tilt variance
        self.pending: deque = (
            deque()
        )  # (stamp_ns, bearing, yaw var, frame_id, wall deadline, t_in, roll/pitch var)
        self.diag = Diagnostics(self, f'tilt corrector ({self.method}, {p["correction"]})')
        self.counts = {
            'stale_imu': 0,
            'no_fix': 0,
            'out_of_domain': 0,
            'no_solution': 0,
            'multiple_solutions': 0,
        }
        t = topics.method_topics(self.method)
        self.pub_heading = self.create_publisher(Imu, t['heading'], qos_profile_system_default)
        self.pub_bearing = self.create_publisher(Float64, t['bearing'], qos_profile_system_default)
        self.pub_status = self.create_publisher(
            String, t['correction_status'], QoSProfile(depth=50)
        )
        self.create_subscription(Imu, t['heading_raw'], self._on_heading, QoSProfile(depth=50))
        imu_qos = QoSProfile(depth=topics.IMU_DEPTH, reliability=ReliabilityPolicy.BEST_EFFORT)
        self.create_subscription(Imu, topics.IMU, self._on_imu, imu_qos)
        if p['site_source'] == 'navsatfix':
            self.create_subscription(NavSatFix, topics.FIX, self._on_fix, qos_profile_sensor_data)
        self.create_timer(
            0.1, self._expire, clock=_wall_clock()
        )  # waits are imu_max_wait_s (0.5 s); IMU arrivals drain too
        self.get_logger().info(
            f'{t["heading_raw"]} + {topics.IMU} -> {t["heading"]} ({p["correction"]}, '
            f'site from {p["site_source"]})'
        )

    def _on_change(self, changed: dict):
        if not hasattr(self, 'sun'):
            return None
        merged = {**self.params.values, **changed}
        try:
            if {'correction', 'error_map'} & set(changed):
                self.corrector = (
                    load_corrector(merged['error_map'], self.method)
                    if merged['correction'] == 'error_map'
                    else None
                )
            if set(SUN_PARAMS) & set(changed):
                sun = sun_source(merged)
                if self.site_from_fix is not None:  # site_source navsatfix: the fix's site stays
                    sun.set_site(*self.site_from_fix)
                self.sun = sun
        except CompassError as exc:
            return str(exc)
        if 'imu_buffer_s' in changed:  # the buffer trims to it from the next sample on
            self.imu.keep_ns = int(merged['imu_buffer_s'] * 1e9)
        return None

    # inputs -------------------------------------------------------------------------------------
    def _on_imu(self, msg):
        q = self.diag.decoded('imu', decode_orientation, msg)
        if q is None:
            return
        self.imu.add(stamp_ns(msg.header), q)
        self.attitude_uncertainty.update(msg.orientation_covariance)
        self._drain()

    def _on_fix(self, msg):
        site = apply_fix(self.sun, self.diag, msg)
        if site is not None:
            self.site_from_fix = site

    def _on_heading(self, msg):
        t_in = self.diag.input()
        heading = self.diag.decoded('heading', heading_from_imu, msg)
        if heading is None:
            return
        bearing, var = heading
        import time

        rp_var = float(msg.orientation_covariance[0])
        rp_var = rp_var if math.isfinite(rp_var) and rp_var > 0 else 1000.0
        self.pending.append(
            (
                stamp_ns(msg.header),
                bearing,
                var,
                msg.header.frame_id,
                time.monotonic() + self.params['imu_max_wait_s'],
                t_in,
                rp_var,
            )
        )
        self._drain()

    def _expire(self):
        self._drain()

    # pairing and correction ---------------------------------------------------------------------
    def _drain(self) -> None:
        """Process the waiting headings whose IMU is available or whose wait is over."""
        import time

        tol_ns = int(self.params['imu_tolerance_s'] * 1e9)
        now = time.monotonic()
        keep = deque()
        while self.pending:
            item = self.pending.popleft()
            t_ns = item[0]
            newest = self.imu.newest_ns
            covered = newest is not None and newest >= t_ns
            if covered or now >= item[4]:
                self._process(item, tol_ns)
            else:
                keep.append(item)
        self.pending = keep

    def _process(self, item, tol_ns: int) -> None:
        t_ns, bearing, var, frame_id, _, t_in, rp_var = item
        p = self.params
        st = {
            'stamp_ns': t_ns,
            'method': self.method,
            'raw_bearing_deg': bearing,
            'correction': p['correction'],
        }
        tilt = self.imu.camera_tilt(t_ns, tol_ns)
        if tilt is None:
            self._reject_without_tilt(st, t_in, t_ns)
            return
        st.update(pitch_deg=tilt.pitch_deg, roll_deg=tilt.roll_deg, imu_gap_ms=tilt.gap_ns / 1e6)
        out_bearing = bearing
        out_var = var
        if self.corrector is not None:
            corrected = self._correct(st, t_in, t_ns, bearing, var, tilt)
            if corrected is None:
                return
            out_bearing, out_var = corrected
        else:
            st.update(status='ok', reason='pass-through')
        self._publish_heading(st, t_in, t_ns, frame_id, bearing, out_bearing, out_var, rp_var)

    def _reject_without_tilt(self, st: dict, t_in, t_ns: int) -> None:
        """Publish and count a heading with no IMU sample near its stamp (none, or all stale)."""
        p = self.params
        newest = self.imu.newest_ns
        why = (
            ('no_imu', 'no IMU sample received')
            if newest is None
            else (
                'stale_imu',
                f'no IMU sample within {p["imu_tolerance_s"]:g} s of the heading '
                f'(nearest newest {abs(t_ns - newest) / 1e9:.3f} s away)',
            )
        )
        self.counts['stale_imu'] += 1
        st.update(status=why[0], reason=why[1], published=False)
        self._status(st)
        self.diag.extra = dict(self.counts)
        self.diag.done(t_in, t_ns, f'{why[0]}: {why[1]}', ok=False)

    def _sun_at(self, st: dict, t_in, t_ns: int):
        """Return the sun's (azimuth, altitude) at the stamp, or None (rejection published)."""
        p = self.params
        if p['site_source'] == 'navsatfix' and self.site_from_fix is None:
            self.counts['no_fix'] += 1
            st.update(
                status='no_fix',
                reason="no NavSatFix received yet (site_source navsatfix): the sun's "
                'position is unknown',
                published=False,
            )
            self._status(st)
            self.diag.extra = dict(self.counts)
            self.diag.done(t_in, t_ns, 'no_fix: no NavSatFix received yet', ok=False)
            return None
        try:
            return self.sun.at_ns(t_ns)
        except CompassError as exc:
            st.update(status='bad_input', reason=str(exc), published=False)
            self._status(st)
            self.diag.done(t_in, t_ns, str(exc), ok=False)
            return None

    def _correct(self, st: dict, t_in, t_ns: int, bearing: float, var: float, tilt):
        """
        Return the error map's corrected bearing and its variance, or None (rejection published).

        The sun's position comes first (no fix, bad input), then the map's correction (out of its
        domain, no or several solutions).
        """
        sun = self._sun_at(st, t_in, t_ns)
        if sun is None:
            return None
        az, alt = sun
        corrected, c = self.corrector.correct_bearing(
            bearing, az, alt, tilt.pitch_deg, tilt.roll_deg
        )
        st.update(sun_azimuth_deg=az, sun_altitude_deg=alt, status=c.status.value, reason=c.reason)
        if not c.ok:
            self.counts[c.status.value] = self.counts.get(c.status.value, 0) + 1
            st['published'] = False
            self._status(st)
            self.diag.extra = dict(self.counts)
            self.diag.done(t_in, t_ns, f'{c.status.value}: {c.reason}', ok=False)
            return None
        return corrected, self._corrected_variance(st, c, alt, tilt, var)

    def _corrected_variance(self, st: dict, c, alt: float, tilt, var: float) -> float:
        """Return the corrected yaw variance: raw + map (correction_sigma_deg) + attitude."""
        p = self.params
        s_tilt, known = self.attitude_uncertainty.sigma_deg(
            float(self.params['attitude_sigma_deg']), self.get_logger()
        )
        s_att = 0.0
        if s_tilt > 0.0:
            sa, sa_ok = self.corrector.attitude_sigma_deg(
                c.psi_deg, alt, tilt.pitch_deg, tilt.roll_deg, s_tilt, s_tilt
            )
            s_att = float(sa[0]) if sa_ok[0] else 0.0
        out_var = var + math.radians(p['correction_sigma_deg']) ** 2 + math.radians(s_att) ** 2
        st.update(
            map_error_deg=c.error_deg,
            attitude_sigma_deg=s_tilt,
            attitude_covariance='imu' if known else 'unknown',
            sigma_attitude_deg=s_att,
        )
        return out_var

    def _publish_heading(
        self, st: dict, t_in, t_ns: int, frame_id: str, bearing, out_bearing, out_var, rp_var
    ) -> None:
        """Publish the (corrected or passed-through) heading, its bearing and its status."""
        yaw = math.radians(90.0 - out_bearing)
        self.pub_heading.publish(
            heading_imu(
                t_ns,
                frame_id or 'base_link',
                math.atan2(math.sin(yaw), math.cos(yaw)),
                out_var,
                rp_var,
            )
        )
        self.pub_bearing.publish(Float64(data=out_bearing))
        st.update(
            bearing_deg=out_bearing, sigma_deg=math.degrees(math.sqrt(out_var)), published=True
        )
        self._status(st)
        self.diag.extra = dict(self.counts)
        self.diag.done(
            t_in, t_ns, f'ok: bearing {out_bearing:.3f} deg (raw {bearing:.3f})', ok=True
        )

    def _status(self, st: dict) -> None:
        self.pub_status.publish(String(data=json.dumps(st, default=str)))


def main(argv=None) -> int:
    return run_node(TiltCorrectorNode, 'tilt_corrector', argv)


if __name__ == '__main__':
    raise SystemExit(main())
