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
Per-frame processing: the nodes' chain for several methods at once.

The chain (:class:`FramePipeline`), one :class:`MethodRow` per method and frame, and the
``tilt_corrector``'s correction (:class:`_Corrector`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
import time

import numpy as np

from .sync import SyncedFrame
from ..bag.topic_map import TopicMap
from ..errors import CompassError
from ..estimators import registry

__all__ = ['ReplayError', 'ReplayConfig', 'MethodRow', 'FramePipeline', 'default_error_map']


class ReplayError(CompassError):
    """Bad replay configuration."""


@dataclass(frozen=True)
class ReplayConfig:
    """
    How frames are processed; defaults are the nodes' shipped parameters (config/*.yaml).

    ``knobs``: per method estimator knobs (``{"*": {...}}`` applies to every method that has the
    knob; a ``"*"`` knob none of the selected methods has is an error). ``default_knobs``: applied
    first to every method that has them, never an error (the nodes ship ``stride: 8``; zenith has
    no stride, so ``--methods zenith`` runs alone). ``prior_source``: imu | last | none
    (heading_estimator ``prior_source``). ``error_map``: .npz from ``polarization-compass
    errormap`` for the tilt correction (None: no corrected headings; see
    :func:`default_error_map`). ``prior_sigma_deg`` and ``polarizer_check_every``: the
    heading_estimator's parameters of those names (the IMU-prior check and the polarizer gate,
    :func:`~polarization_compass.pipeline.apply_rules`). ``attitude_sigma_deg``: the
    heading_estimator's parameter (the tilt 1-sigma [deg] the IMU covariance does not hold; with
    the bag's IMU covariance it grows tilt_aware's sigma as on the node).
    ``principal_point_sigma_px``: the heading_estimator's parameter (the camera's principal point
    1-sigma [px]; None: a calibration's typical one, :mod:`~..pipeline.optical_centre`), which
    grows every heading's sigma as on the node. ``direct_methods``:
    methods the corrector does not touch (default: those whose estimator class ``needs_tilt``,
    e.g. tilt_aware).
    """

    methods: tuple = ()
    knobs: dict = field(default_factory=lambda: {'*': {}})
    default_knobs: dict = field(default_factory=lambda: {'stride': 8})
    demosaic: str = 'superpixel'
    use_intensity: bool = False
    sky_check: bool = False
    prior_source: str = 'imu'
    prior_max_age_s: float = 2.0
    prior_sigma_deg: float = 15.0
    polarizer_check_every: int = 100
    attitude_sigma_deg: float = 0.0
    principal_point_sigma_px: float | None = None
    sun_model: str = 'spa'
    error_map: str | None = None
    correction_sigma_deg: float = 0.1
    direct_methods: tuple = field(default_factory=lambda: registry.tilt_methods())

    def method_list(self) -> list[str]:
        """
        Return the methods to run: ``methods``, or every registered estimator when empty.

        Returns
        -------
        list of str
            Estimator names, in the given order.

        Raises
        ------
        ReplayError
            A name that is not a registered estimator.

        """
        from ..estimators import estimator_names

        known = estimator_names()
        ms = list(self.methods) or known
        bad = [m for m in ms if m not in known]
        if bad:
            raise ReplayError(f'unknown method(s) {", ".join(bad)}; known: {", ".join(known)}')
        return ms

    def knobs_for(self, method: str) -> dict:
        """
        Return the estimator knobs of ``method``.

        The ``default_knobs`` it has, then the ``"*"`` entries it has (zenith has no stride, for
        example), then its own entries (an unknown name there is an error of the estimator).

        Parameters
        ----------
        method : str
            Estimator name.

        Returns
        -------
        dict
            ``{knob: value}`` for the estimator's constructor.

        """
        from ..estimators import estimator_knob_names

        names = estimator_knob_names(method)
        k = {n: v for n, v in self.default_knobs.items() if n in names}
        k.update({n: v for n, v in self.knobs.get('*', {}).items() if n in names})
        k.update(self.knobs.get(method, {}))
        return k

    def for_methods(self, methods) -> 'ReplayConfig':
        """
        Return this configuration for a subset of its methods (a worker's group).

        ``"*"`` keeps the knobs one of them has, so that :meth:`check_knobs`, already passed by the
        whole set, passes again.

        Parameters
        ----------
        methods : iterable of str
            The subset.

        Returns
        -------
        ReplayConfig
            A copy with those methods and knobs.

        """
        from ..estimators import estimator_knob_names

        names = set().union(*(estimator_knob_names(m) for m in methods))
        knobs = {k: v for k, v in self.knobs.items() if k != '*'}
        knobs['*'] = {n: v for n, v in self.knobs.get('*', {}).items() if n in names}
        return dataclasses.replace(self, methods=tuple(methods), knobs=knobs)

    def check_knobs(self) -> None:
        """
        Check that every ``"*"`` knob belongs to a selected method (a typo, not a no-op).

        Raises
        ------
        ReplayError
            An unknown method, or a ``"*"`` knob no selected method has.

        """
        from ..estimators import estimator_knob_names

        ms = self.method_list()
        known = set().union(*(estimator_knob_names(m) for m in ms))
        bad = sorted(set(self.knobs.get('*', {})) - known)
        if bad:
            raise ReplayError(
                f'unknown knob(s) {", ".join(bad)} for methods {", ".join(ms)}; '
                f'known: {", ".join(sorted(known))}'
            )


@dataclass(kw_only=True)
class MethodRow:
    """
    One method on one frame: the raw estimate, its tilt correction and the errors (deg).

    Built by keyword only; a row of a frame that was not estimated (``bad_input``) leaves the
    estimate, correction and error fields at their defaults (None, ``""``, 0 pixels).

    ``raw_error_deg``/``corrected_error_deg``: estimated minus reference bearing, wrapped to (-180,
    180] (None when not evaluated: no reference, an ambiguous or failed estimate, no correction).
    """

    stamp_ns: int
    method: str
    status: str
    reason: str
    raw_bearing_deg: float | None = None
    corrected_bearing_deg: float | None = None
    correction_status: str = ''
    reference_bearing_deg: float | None = None
    raw_error_deg: float | None = None
    corrected_error_deg: float | None = None
    sigma_deg: float | None = None
    pixels: int = 0
    pitch_deg: float | None = None
    roll_deg: float | None = None
    sun_azimuth_deg: float = 0.0
    sun_altitude_deg: float = 0.0
    prior_bearing_deg: float | None = None

    CSV_FIELDS = (
        'stamp_s',
        'time_s',
        'method',
        'status',
        'raw_bearing_deg',
        'corrected_bearing_deg',
        'reference_bearing_deg',
        'raw_error_deg',
        'corrected_error_deg',
        'correction_status',
        'sigma_deg',
        'pixels',
        'pitch_deg',
        'roll_deg',
        'sun_azimuth_deg',
        'sun_altitude_deg',
        'prior_bearing_deg',
        'reason',
    )


class FramePipeline:
    """The nodes' per-frame chain for several methods at once (see the module docstring)."""

    def __init__(self, config: ReplayConfig, topic_map: TopicMap):
        from ..mosaic import layout_from_mapping
        from ..pipeline.front_end import HeadingFrontEnd
        from ..pipeline.monitors import PolarizerMonitor
        from ..pipeline.prior import TiltAndPrior
        from ..pipeline.rules import SensorReadout

        self.readout = SensorReadout(topic_map.readout_flip)  # the node's readout_flip
        layout = layout_from_mapping(topic_map.mosaic)
        self.config = config
        config.check_knobs()
        self.methods = config.method_list()
        self.fronts = {
            m: HeadingFrontEnd(
                m,
                config.knobs_for(m),
                layout,
                layout.pol45_toward,
                config.demosaic,
                config.use_intensity,
                principal_point_sigma_px=config.principal_point_sigma_px,
            )
            for m in self.methods
        }
        self.tilt_prior = {
            m: TiltAndPrior(m, config.prior_source, config.prior_max_age_s, config.prior_sigma_deg)
            for m in self.methods
        }
        self.polarizer = PolarizerMonitor(config.polarizer_check_every)  # one per frame stream
        self.sun = None
        self.corrector = None
        if config.error_map:  # (replay_bag checked the map against all the methods)
            self.corrector = _make_corrector(config, check_methods=False)
        self.timing_ms: dict = {m: [] for m in self.methods}
        self.timing_ms['observation'] = []

    def _sun(self, frame: SyncedFrame):
        from ..pipeline.sun import SunSource

        if self.sun is None:
            self.sun = SunSource(*frame.site, model=self.config.sun_model)
        else:
            self.sun.set_site(*frame.site)
        return self.sun.at_ns(frame.stamp_ns)

    def process(self, frame: SyncedFrame) -> list[MethodRow]:
        """
        Run every method on one synchronised frame, as the nodes would.

        Sun position at the stamp, per-method prior and tilt, one observation per demosaic front
        (shared), the estimate, and the tilt correction (or ``pending`` when deferred).

        Parameters
        ----------
        frame : SyncedFrame
            The image with its camera, site, IMU tilt and reference bearing.

        Returns
        -------
        list of MethodRow
            One row per method; a frame that cannot be estimated (no sun, no tilt for a method that
            needs it, bad input) gives rows with status ``bad_input`` and the reason.

        """
        from ..pipeline.errors import PipelineError

        try:
            sun_az, sun_alt = self._sun(frame)
        except PipelineError as exc:
            return [
                MethodRow(
                    stamp_ns=frame.stamp_ns,
                    method=m,
                    status='bad_input',
                    reason=str(exc),
                    reference_bearing_deg=frame.true_bearing_deg,
                )
                for m in self.methods
            ]
        obs_cache: dict = {}  # one observation per demosaic front, one whole-sky sample
        # a mirrored readout read back as the sensor sees it, K mirrored with it (the node's)
        mosaic, camera = self.readout.image(frame.mosaic), self.readout.camera(frame.camera)
        frame = dataclasses.replace(frame, mosaic=mosaic, camera=camera)
        self._check_polarizer(frame, sun_alt)
        return [
            self._method_row(m, front, frame, sun_az, sun_alt, obs_cache)
            for m, front in self.fronts.items()
        ]

    def _check_polarizer(self, frame: SyncedFrame, sun_alt: float) -> None:
        """Feed the frame to the polarizer check as the node does (level); never fatal."""
        layout = next(iter(self.fronts.values())).layout
        try:
            self.polarizer.feed(frame.mosaic, frame.camera, layout, sun_alt)
        except CompassError:  # the node logs a failing check and goes on; so does replay
            pass

    def _method_row(self, m, front, frame, sun_az, sun_alt, obs_cache: dict) -> MethodRow:
        """Run method ``m`` on the frame: prior, tilt, estimate, the node's rules, correction."""
        from ..pipeline.attitude_sigma import tilt_sigma_deg
        from ..pipeline.rules import apply_rules

        c = self.config
        t_ns, tilt = frame.stamp_ns, frame.tilt
        inp = self.tilt_prior[m].inputs(t_ns, tilt, frame.imu_near)
        pitch, roll, prior = inp.pitch_deg, inp.roll_deg, inp.prior_bearing_deg
        common = {
            'stamp_ns': t_ns,
            'method': m,
            'reference_bearing_deg': frame.true_bearing_deg,
            'sun_azimuth_deg': sun_az,
            'sun_altitude_deg': sun_alt,
            'prior_bearing_deg': prior,
        }
        if inp.tilt_missing:
            return MethodRow(
                status='bad_input',
                reason='no IMU sample near the image stamp (tilt unknown)',
                **common,
            )
        key = front.observation_key(frame.camera)
        t0 = time.perf_counter()
        try:
            result, t0 = self._estimate(front, frame, inp, key, sun_az, sun_alt, obs_cache, t0)
            tilt_sigma = (  # the latest IMU's covariance plus attitude_sigma_deg, as the node's
                tilt_sigma_deg(frame.imu_tilt_var_deg2, c.attitude_sigma_deg),
                frame.imu_tilt_var_deg2 is not None,
            )
            result = apply_rules(result, inp, self.tilt_prior[m], self.polarizer, tilt_sigma)
        except CompassError as exc:
            return MethodRow(
                status='bad_input', reason=str(exc), pitch_deg=pitch, roll_deg=roll, **common
            )
        self.timing_ms[m].append((time.perf_counter() - t0) * 1e3)
        raw = result.bearing_deg if result.ok and not result.axial else None
        self.tilt_prior[m].remember(t_ns, result)
        corrected, cstatus = None, ''
        if raw is not None and m not in c.direct_methods and self.corrector is not None:
            corrected, cstatus = self.corrector(m, raw, result, tilt, sun_az, sun_alt, t_ns)
        return MethodRow(
            status=result.status.value,
            reason=result.reason,
            raw_bearing_deg=float(result.bearing_deg) if result.ok else None,
            corrected_bearing_deg=corrected,
            correction_status=cstatus,
            sigma_deg=result.sigma_deg,
            pixels=result.pixels,
            pitch_deg=tilt.pitch_deg if tilt is not None else None,
            roll_deg=tilt.roll_deg if tilt is not None else None,
            **common,
        )

    def _estimate(self, front, frame, inp, key, sun_az, sun_alt, obs_cache: dict, t0: float):
        """
        Return a method's result on the frame, and when its own time [perf_counter s] started.

        The observation is computed once per demosaic front (``key``) and shared, its time counted
        as ``observation``; with ``sky_check`` the result is assessed on one whole-sky sample per
        frame (skyfit). Raises :class:`~polarization_compass.errors.CompassError` for bad input.
        """
        obs = obs_cache.get(key)
        if obs is None:
            obs = front.observation(frame.mosaic, frame.camera, sun_az, sun_alt)
            obs_cache[key] = obs
            self.timing_ms['observation'].append((time.perf_counter() - t0) * 1e3)
            t0 = time.perf_counter()
        from ..pipeline.front_end import estimate_checked

        pitch, roll, prior = inp.pitch_deg, inp.roll_deg, inp.prior_bearing_deg
        obs = dataclasses.replace(obs, pitch_deg=pitch, roll_deg=roll, prior_bearing_deg=prior)
        check = self.config.sky_check
        if check and 'sky' not in obs_cache:  # the whole-sky check's sample, one per frame
            from ..pipeline.sampling import whole_sky_sample

            obs_cache['sky'] = whole_sky_sample(frame.mosaic, frame.camera, front.layout)
        res = estimate_checked(
            front.estimator, obs, check, obs_cache.get('sky'), front.principal_point_sigma_px
        )
        return res, t0


def default_error_map() -> str | None:
    """
    Return the error map shipped with the package (the ``tilt_corrector`` node's default).

    Returns
    -------
    str or None
        Its path, or None when the package has none.

    """
    from ..correction import default_map_path

    p = default_map_path()
    return str(p) if p.is_file() else None


def _make_corrector(config: ReplayConfig, check_methods: bool = True):
    """
    Return the ``tilt_corrector`` node's correction as a :class:`_Corrector`, map checked now.

    Every documented format loads (``.npz``, NetCDF, a Zarr store directory). A map that cannot be
    read, or (``check_methods``: the whole replay's configuration, not one worker group's) that
    corrects none of the selected methods, is a :class:`ReplayError` (exit 2 with the reason)
    before any frame is read, never an empty corrected stream.
    """
    from ..errormap import ErrorMapError
    from ..errormap_io import load_error_map

    path = Path(config.error_map)
    if not path.exists():
        raise ReplayError(
            f'error map {str(path)!r} does not exist: make one with `polarization-compass '
            'errormap '
            '--methods zenith,sm_asm,symmetry,least_squares --sun-altitude 0:50:5 --yaw '
            '-180:175:5 '
            '--pitch -30:30:5 --roll -30:30:5 --out MAP.npz`'
        )
    try:
        emap = load_error_map(path)
    except ErrorMapError as exc:
        raise ReplayError(f'--error-map: {exc}') from None
    cor = _Corrector(path, emap)
    if not check_methods:
        return cor
    wanted = [m for m in config.method_list() if m not in config.direct_methods]
    reasons = {m: cor._get(m) for m in wanted}
    reasons = {m: r for m, r in reasons.items() if isinstance(r, str)}
    if wanted and len(reasons) == len(wanted):
        raise ReplayError(
            f'--error-map {str(path)!r} corrects none of the methods '
            f'{", ".join(wanted)}: ' + '; '.join(f'{m}: {r}' for m, r in reasons.items())
        )
    return cor


class _Corrector:
    """
    The ``tilt_corrector`` node's correction of one heading.

    ``(method, raw_bearing_deg, result, tilt, sun_az, sun_alt, t_ns) -> (corrected_bearing_deg |
    None, status)``: :meth:`TiltCorrector.correct_bearing` (the node's) at the IMU's pitch/roll; a
    heading without an IMU tilt near its stamp is not corrected (``no_imu``).

    With ``defer`` on, headings are queued (status ``pending``) and :meth:`resolve` corrects them
    all with one vectorised inversion per method (:meth:`TiltCorrector.correct_bearings`, same
    numbers): an inversion costs about 8 ms whether it holds one heading or a thousand, which made
    correction the largest cost of an offline replay.
    """

    PENDING = 'pending'

    def __init__(self, path: Path, error_map=None):
        self.path = path
        self._map = error_map  # loaded on first use when not given
        self.correctors: dict = {}
        self.defer = False
        self.queue: list = []  # (row, method, raw, sun_az, sun_alt, pitch, roll)

    def _get(self, method):
        from ..correction import TiltCorrector
        from ..errormap import ErrorMapError
        from ..errormap_io import load_error_map

        if method not in self.correctors:
            try:
                if self._map is None:
                    self._map = load_error_map(self.path)  # once for every method's corrector
                self.correctors[method] = TiltCorrector(self._map, method)
            except ErrorMapError as exc:
                self.correctors[method] = str(exc)
        return self.correctors[method]

    def __call__(self, method, raw_bearing_deg, result, tilt, sun_az, sun_alt, t_ns):
        if tilt is None:
            return None, 'no_imu'
        if self.defer:
            return None, self.PENDING  # the map is read when the queue is resolved
        cor = self._get(method)
        if isinstance(cor, str):
            return None, 'no_map'
        corrected, c = cor.correct_bearing(
            raw_bearing_deg, sun_az, sun_alt, tilt.pitch_deg, tilt.roll_deg
        )
        return corrected, c.status.value

    def enqueue(self, row) -> None:
        """Queue a row whose ``correction_status`` is ``pending``."""
        self.queue.append(row)

    def resolve(self) -> None:
        """Correct every queued row in place (``corrected_bearing_deg``, ``correction_status``)."""
        by_method: dict = {}
        for row in self.queue:
            by_method.setdefault(row.method, []).append(row)
        for method, rows in by_method.items():
            cor = self._get(method)
            if isinstance(cor, str):  # the map has no layer for this method
                for r in rows:
                    r.corrected_bearing_deg, r.correction_status = None, 'no_map'
                continue
            cols = np.array(
                [
                    (
                        r.raw_bearing_deg,
                        r.sun_azimuth_deg,
                        r.sun_altitude_deg,
                        r.pitch_deg,
                        r.roll_deg,
                    )
                    for r in rows
                ],
                dtype=float,
            )
            fixed = cor.correct_bearings(*cols.T)
            for r, b, ok, st in zip(rows, fixed.bearing_deg, fixed.ok, fixed.status):
                r.corrected_bearing_deg = float(b) if ok else None
                r.correction_status = st
        self.queue = []
