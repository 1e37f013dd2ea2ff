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
The error budget: heading accuracy per method and the cost of each declared effect.

The error budget: what heading accuracy a scene gives, per method, and what each declared effect
costs.

A Monte Carlo over ``samples`` frames of a scene (its site, time/sun, camera, sky, atmosphere,
optics and sensor as declared), each with a random bearing (uniform), a random tilt (``|pitch| +
|roll| <= tilt_max_deg``, as the accuracy benchmark samples it), the scene's seed varied per sample
(a new cloud field, new sensor noise) and the IMU/mounting errors of
:class:`~polarization_compass.motion.MountingErrors` applied to the pitch and roll the pipeline
is given. Every method of the registry estimates every frame, as the ROS graph does: tilt-aware
methods read the IMU's pitch and roll; the others are tilt-corrected with the error map at those
(erroneous) pitch and roll (:class:`~polarization_compass.correction.TiltCorrector`, inversion;
``correction "none"`` reports their raw tilt error instead), so ``tilt`` is the residual after
correction. Both propagate the attitude's stated 1-sigma (:meth:`MountingErrors.tilt_sigma_deg`)
into sigma: ``J Sigma_att J^T``, J = d psi / d(pitch, roll) (the map's gradient, or the method's
own). Per method it reports the heading error's RMS, p95 and max over the ok results, the share of
results that are not ok (a failed correction included), and the sigma calibration ``mean(err^2 /
sigma^2)`` (1 for an honest sigma).

The breakdown by source repeats the run with one declared source switched off, on the same samples
(same bearings, tilts, seeds and IMU draws: paired), and reports the RMS without it and its
contribution ``sqrt(max(0, RMS_all^2 - RMS_without^2))`` (deg; sources are not independent, so
contributions need not add up to the total). Sources: ``noise`` (sensor shot/read noise,
quantisation), ``calibration`` (DoFP calibration errors), ``clouds``, ``haze``, ``skyline``,
``ground`` (the reflection below the horizon, which only methods without validity masks see),
``optics`` (sun glare, flare, vignetting), ``sky_model`` (a non-Rayleigh sky against the Rayleigh
one the estimators assume, same DoP_max), ``tilt`` (the camera level instead), ``imu`` (noise,
bias, time offset) and ``boresight``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import functools
import math

import numpy as np

from .conventions import CameraAttitude, fold_axial_deg, wrap_180_deg
from .errors import CompassError
from .motion import MountingErrors
from .scene import Scene

__all__ = [
    'BudgetError',
    'BudgetConfig',
    'SOURCES',
    'SIGMA_BAND',
    'declared_sources',
    'run_budget',
    'check_config',
    'parse_imu',
    'plot_budget',
]

_NOISE_KEYS = ('shot_noise', 'read_noise', 'quantization')
SOURCES = (
    'noise',
    'calibration',
    'clouds',
    'haze',
    'skyline',
    'ground',
    'optics',
    'sky_model',
    'tilt',
    'imu',
    'boresight',
)


#: The band of ``mean(err^2 / sigma^2)`` taken as honest. The mean of N chi^2_1 draws has a
#: standard deviation of sqrt(2 / N) (0.14 at N = 100), but a budget's errors are neither Gaussian
#: nor independent (one fixed calibration pattern, one cloud field per frame), hence the wide band.
SIGMA_BAND = (0.3, 3.0)


class BudgetError(CompassError):
    """Unusable budget input (no method, bad --imu, no samples)."""


def published_sigma_floor_deg() -> float:
    """
    Return heading_estimator's default ``sigma_floor_deg`` (specs/params/).

    Returns
    -------
    float
        The smallest yaw sigma the node publishes [deg]: the model error of real skies.

    """
    from .specs.params import defaults, ESTIMATOR

    return float(defaults(ESTIMATOR)['sigma_floor_deg'])


@dataclass(frozen=True)
class BudgetConfig:
    """
    What an error budget runs: a scene, the sampling and the IMU/mounting errors.

    Attributes
    ----------
    scene : Scene
        The scene (site, time/sun, camera, sky, atmosphere, optics, sensor); its seed seeds the
        samples.
    samples : int, default 50
        Monte Carlo frames per condition.
    tilt_max_deg : float, default 0
        Largest ``|pitch| + |roll|`` of the sampled attitudes [deg]; 0 keeps the camera level.
    imu : MountingErrors, default no errors
        IMU and mounting errors applied to the pitch and roll that tilt-aware methods read.
    methods : tuple of str, default ()
        Method names of the estimator registry to run; empty runs every registered method.
    correction : {"error_map", "none"}, default "error_map"
        What the graph's ``tilt_corrector`` does to methods that do not read the tilt: invert
        their tilt error with the error map at the IMU's (erroneous) pitch and roll, or nothing
        (their raw tilt error).
    error_map : str, optional
        The error map ``.npz``; None = the map shipped with the package.
    correction_sigma_deg : float, default 0
        1-sigma of the map's own error for this camera and sky [deg] (interpolation and a map made
        for another camera), added in quadrature to corrected methods' sigmas, as the node's
        ``correction_sigma_deg`` parameter.
    sigma_floor_deg : float, default: heading_estimator's ``sigma_floor_deg`` (0.01)
        The smallest sigma a node publishes (the model error of real skies); the sigma
        calibration is computed with ``max(sigma, floor)``, what a robot receives
        (``sigma_calibration_raw`` without it).

    """

    scene: Scene
    samples: int = 50
    tilt_max_deg: float = 0.0
    imu: MountingErrors = MountingErrors()
    methods: tuple = ()
    correction: str = 'error_map'
    error_map: str | None = None
    correction_sigma_deg: float = 0.0
    sigma_floor_deg: float = field(default_factory=published_sigma_floor_deg)


def parse_imu(text: str | None) -> MountingErrors:
    """
    Parse ``key=value,...`` into :class:`MountingErrors`.

    Keys are the fields of :class:`~polarization_compass.motion.MountingErrors` (angles [deg],
    ``time_offset_s`` [s], ``tilt_rate_deg_s`` [deg/s]), plus ``bias_deg`` (sets both tilt biases)
    and ``boresight_deg`` (sets the roll and pitch boresight). Empty parts are skipped.

    Parameters
    ----------
    text : str or None
        The ``--imu`` argument, e.g. ``"noise_deg=0.5,bias_deg=0.2"``; None or empty for no
        errors.

    Returns
    -------
    MountingErrors
        The parsed errors.

    Raises
    ------
    BudgetError
        For a part without ``=``, a value that is not a number, an unknown key, or values that
        :class:`MountingErrors` rejects.

    """
    if not text:
        return MountingErrors()
    vals = {}
    for part in text.split(','):
        if not part.strip():
            continue
        if '=' not in part:
            raise BudgetError(f'--imu: expected key=value, got {part!r}')
        k, v = (s.strip() for s in part.split('=', 1))
        try:
            f = float(v)
        except ValueError:
            raise BudgetError(f'--imu: {k} must be a number, got {v!r}') from None
        if k == 'bias_deg':
            vals.update(pitch_bias_deg=f, roll_bias_deg=f)
        elif k == 'boresight_deg':
            vals.update(boresight_roll_deg=f, boresight_pitch_deg=f)
        elif k in MountingErrors.FIELDS:
            vals[k] = f
        else:
            raise BudgetError(
                f'--imu: unknown key {k!r}; known: bias_deg, boresight_deg, '
                f'{", ".join(MountingErrors.FIELDS)}'
            )
    try:
        return MountingErrors(**vals)
    except ValueError as exc:
        raise BudgetError(f'--imu: {exc}') from None


def declared_sources(cfg: BudgetConfig) -> list[str]:
    """
    Return the sources of error the configuration declares, in :data:`SOURCES` order.

    Parameters
    ----------
    cfg : BudgetConfig
        The budget configuration.

    Returns
    -------
    list of str
        The names of :data:`SOURCES` that are switched on: sensor noise keys, DoFP calibration,
        clouds, haze, skyline, ground, optics, a non-Rayleigh sky model, ``tilt_max_deg > 0``,
        IMU errors, boresight errors.

    """
    s = cfg.scene
    atm = s.atmosphere or {}
    on = {
        'noise': any(k in s.sensor for k in _NOISE_KEYS),
        'calibration': 'calibration' in s.sensor,
        'clouds': atm.get('clouds') is not None,
        'haze': atm.get('haze') is not None,
        'skyline': atm.get('skyline') is not None,
        'ground': atm.get('ground') is not None,
        'optics': bool(s.optics),
        'sky_model': (s.sky or {}).get('model', 'rayleigh') != 'rayleigh',
        'tilt': cfg.tilt_max_deg > 0,
        'imu': cfg.imu.has_imu,
        'boresight': cfg.imu.has_boresight,
    }
    return [k for k in SOURCES if on[k]]


def without(cfg: BudgetConfig, source: str) -> BudgetConfig:
    """
    Return the configuration with ``source`` switched off.

    ``sky_model`` is replaced by the Rayleigh sky of the same ``dop_max``; ``tilt`` sets
    ``tilt_max_deg`` to 0; the others drop their sensor keys, atmosphere entry, optics or IMU
    errors.

    Parameters
    ----------
    cfg : BudgetConfig
        The budget configuration.
    source : str
        One of :data:`SOURCES`.

    Returns
    -------
    BudgetConfig
        A new configuration; ``cfg`` is unchanged.

    Raises
    ------
    BudgetError
        When ``source`` is not one of :data:`SOURCES`.

    """
    import dataclasses

    s = cfg.scene
    if source == 'noise':
        return dataclasses.replace(
            cfg,
            scene=s.replace(sensor={k: v for k, v in s.sensor.items() if k not in _NOISE_KEYS}),
        )
    if source == 'calibration':
        return dataclasses.replace(
            cfg, scene=s.replace(sensor={k: v for k, v in s.sensor.items() if k != 'calibration'})
        )
    if source in ('clouds', 'haze', 'skyline', 'ground'):
        atm = {k: v for k, v in (s.atmosphere or {}).items() if k != source}
        return dataclasses.replace(cfg, scene=s.replace(atmosphere=atm or None))
    if source == 'optics':
        return dataclasses.replace(cfg, scene=s.replace(optics=None))
    if source == 'sky_model':
        return dataclasses.replace(
            cfg,
            scene=s.replace(
                sky={'model': 'rayleigh', 'dop_max': float(s.sky.get('dop_max', 1.0))}
            ),
        )
    if source == 'tilt':
        return dataclasses.replace(cfg, tilt_max_deg=0.0)
    if source in ('imu', 'boresight'):
        return dataclasses.replace(cfg, imu=cfg.imu.without(source))
    raise BudgetError(f'unknown source {source!r}')


def _samples(cfg: BudgetConfig):
    """
    Draw the seeded per-sample attitudes, scene seeds and IMU normals.

    Seeded (bearing, pitch, roll, scene seed, IMU normals) per sample, from the scene's seed only.
    """
    out = []
    for i in range(cfg.samples):
        rng = np.random.default_rng([cfg.scene.seed, 0xB0D6, i])
        bearing = float(rng.uniform(0.0, 360.0))
        pitch = float(rng.uniform(-1.0, 1.0))
        roll = float(rng.uniform(-1.0, 1.0)) * (
            1.0 - abs(pitch)
        )  # |pitch| + |roll| <= 1, scaled below
        seed = int(rng.integers(0, 2**31 - 1))
        out.append((bearing, pitch, roll, seed, rng.standard_normal(3)))
    return out


def _stats(errs, statuses_ok, sigmas, floor_deg: float = 0.0) -> dict:
    n = len(statuses_ok)
    e = np.abs(np.asarray(errs, dtype=float))
    d = {'count': n, 'ok': int(e.size), 'share_not_ok': (n - e.size) / n if n else None}
    if e.size:
        d.update(
            rms_deg=float(np.sqrt(np.mean(e**2))),
            p95_deg=float(np.percentile(e, 95)),
            max_deg=float(e.max()),
        )
    else:
        d.update(rms_deg=None, p95_deg=None, max_deg=None)
    pairs = [(x, s) for x, s in zip(errs, sigmas) if s is not None and s > 0]
    cal = float(np.mean([(x / max(s, floor_deg)) ** 2 for x, s in pairs])) if pairs else None
    d['sigma_calibration'] = cal
    raw = float(np.mean([(x / s) ** 2 for x, s in pairs])) if pairs else None
    d['sigma_calibration_raw'] = raw
    d['sigma_floor_deg'] = floor_deg
    d['sigma_count'] = len(pairs)
    d['sigma_band'] = (
        None
        if cal is None
        else 'overconfident'
        if cal > SIGMA_BAND[1]
        else 'conservative'
        if cal < SIGMA_BAND[0]
        else 'honest'
    )
    return d


def _run_condition(cfg: BudgetConfig, samples, methods) -> dict:
    raw = _condition_part(cfg, samples, methods)
    return {m: _stats(*raw[m], floor_deg=cfg.sigma_floor_deg) for m in methods}


def _budget_task(cfg: BudgetConfig, samples, methods) -> dict:
    """
    Run some samples of one condition on a Dask worker (numba on one thread).

    Run on a Dask worker: the raw results of some samples of one condition, numba on one thread.
    """
    from .runtime import keep_large_buffers_in_heap, single_threaded_kernels

    keep_large_buffers_in_heap()
    with single_threaded_kernels():
        return _condition_part(cfg, samples, methods)


@functools.lru_cache(maxsize=4)
def _error_map(path: str | None):
    """Load the error map at ``path`` (None = the shipped one), once per process."""
    from .correction import default_map_path
    from .errormap import ErrorMapError
    from .errormap_io import load_error_map

    try:
        return load_error_map(default_map_path() if path is None else path)
    except (ErrorMapError, OSError) as exc:
        raise BudgetError(f'error map {path or "(shipped)"}: {exc}') from None


@functools.lru_cache(maxsize=16)
def _corrector(path: str | None, method: str):
    """Build the TiltCorrector of ``method`` from ``path`` (None = shipped map), once."""
    from .correction import TiltCorrector
    from .errormap import ErrorMapError

    try:
        return TiltCorrector(_error_map(path), method)
    except ErrorMapError as exc:
        raise BudgetError(f'error map {path or "(shipped)"}: {exc}') from None


def corrected_methods(cfg: BudgetConfig, methods) -> list[str]:
    """
    Return the methods the budget tilt-corrects with the error map, as the graph's corrector does.

    Parameters
    ----------
    cfg : BudgetConfig
        The budget configuration.
    methods : sequence of str
        The methods run.

    Returns
    -------
    list of str
        The methods that do not read the tilt and have errors in the map (none with ``correction
        "none"``).

    Raises
    ------
    BudgetError
        The map cannot be read or its yaw axis is unusable for correction.

    """
    from .estimators import registry

    if cfg.correction == 'none':
        return []
    have = set(_error_map(cfg.error_map).methods)
    out = [m for m in methods if not registry.get(m).needs_tilt and m in have]
    for m in out:
        _corrector(cfg.error_map, m)  # an unusable yaw axis raises here, not in a worker
    return out


def _condition_part(cfg: BudgetConfig, samples, methods) -> dict:
    """
    Per method ([errors], [ok flags], [sigmas]) over ``samples``, in their order.

    Tilt-aware methods read the IMU's pitch and roll with their stated 1-sigma
    (:meth:`MountingErrors.tilt_sigma_deg`, propagated by the method); the others are corrected
    with the error map at that pitch and roll (:meth:`TiltCorrector.correct`), their sigma grown
    by the propagated attitude uncertainty and ``correction_sigma_deg``; a failed correction is a
    result that is not ok.
    """
    from .estimators import registry
    from .estimators.base import Observation
    from .render import Renderer

    estimators = {m: registry.make(m) for m in methods}
    needs_tilt = {m: bool(registry.get(m).needs_tilt) for m in methods}
    fix = {m: _corrector(cfg.error_map, m) for m in corrected_methods(cfg, methods)}
    res = {m: ([], [], []) for m in methods}
    for bearing, p, r, seed, normals in samples:
        att = CameraAttitude(bearing, p * cfg.tilt_max_deg, r * cfg.tilt_max_deg)
        scene = cfg.scene.replace(seed=seed)
        frame = Renderer(scene).render(attitude=att)
        seen = cfg.imu.measured_attitude(att, normals)
        att_sigma = cfg.imu.tilt_sigma_deg(math.hypot(seen.pitch_deg, seen.roll_deg))
        for m in methods:
            obs = Observation.from_frame(frame, camera=scene.camera)
            if needs_tilt[m]:
                obs.pitch_deg, obs.roll_deg = seen.pitch_deg, seen.roll_deg
                obs.attitude_sigma_deg = att_sigma
            out = estimators[m].estimate(obs)
            psi, sigma, ok = out.psi_deg, out.sigma_deg, bool(out.ok)
            if ok and m in fix:
                h = float(frame.sun.altitude_deg)
                c = fix[m].correct(psi, h, seen.pitch_deg, seen.roll_deg)
                ok = c.ok
                if ok:
                    psi = c.psi_deg
                    s_att, _ = fix[m].attitude_sigma_deg(
                        psi, h, seen.pitch_deg, seen.roll_deg, *att_sigma
                    )
                    sigma = math.sqrt(
                        sigma**2 + float(s_att[0]) ** 2 + cfg.correction_sigma_deg**2
                    )
            errs, oks, sig = res[m]
            oks.append(ok)
            if ok:
                d = psi - frame.psi_deg
                errs.append(float(fold_axial_deg(d)) if out.axial else float(wrap_180_deg(d)))
                sig.append(sigma)
    return res


def _run_conditions_on_dask(conds, samples, methods, scheduler, workers, progress) -> dict:
    """
    Run every (condition, block of samples) as a Dask task, joined in sample order.

    The statistics equal the in-process ones (each block runs numba on one thread).
    """
    from .sweep_dask import run_tasks

    n = max(1, int(workers or 0) or 2)
    block = max(1, math.ceil(len(samples) / (4 * n)))
    calls, parts = [], {}
    for ci, (name, c) in enumerate(conds):
        for bi, i in enumerate(range(0, len(samples), block)):
            calls.append(
                (
                    f'budget-{ci}-{bi}-{id(calls)}',
                    _budget_task,
                    (c, samples[i : i + block], methods),
                )
            )

    def on_result(key, raw):
        _, ci, bi, _ = key.split('-')
        parts[(int(ci), int(bi))] = raw
        if progress and all((int(ci), b) in parts for b in range(math.ceil(len(samples) / block))):
            progress(conds[int(ci)][0])

    run_tasks(calls, on_result, scheduler=scheduler, workers=workers)
    out = {}
    for ci, (name, c) in enumerate(conds):
        blocks = [parts[(ci, b)] for b in range(math.ceil(len(samples) / block))]
        out[name] = {
            m: _stats(
                *[sum((bl[m][k] for bl in blocks), []) for k in range(3)],
                floor_deg=c.sigma_floor_deg,
            )
            for m in methods
        }
    return out


#: Largest camera a budget renders: 2^25 pixels per frame, as a frame file
#: (:data:`~polarization_compass.frame_io.MAX_FRAME_PIXELS`).
MAX_BUDGET_PIXELS = 1 << 25


def check_config(cfg: BudgetConfig) -> list:
    """
    Check a budget's configuration before anything is computed; return its methods.

    Parameters
    ----------
    cfg : BudgetConfig
        The configuration.

    Returns
    -------
    list of str
        The methods to run (all registered ones when ``cfg.methods`` is empty).

    Raises
    ------
    BudgetError
        No samples, an unknown method or correction, a negative or non-finite sigma, negative IMU
        noise, or a camera of more than :data:`MAX_BUDGET_PIXELS` pixels (a frame of it would take
        gigabytes).

    """
    from .estimators import registry

    if cfg.samples < 1:
        raise BudgetError('samples must be >= 1')
    methods = list(cfg.methods) or list(registry.names())
    unknown = [m for m in methods if m not in registry.names()]
    if unknown:
        raise BudgetError(f'unknown method(s) {unknown}; known: {", ".join(registry.names())}')
    if cfg.correction not in ('error_map', 'none'):
        raise BudgetError(f"correction must be 'error_map' or 'none', got {cfg.correction!r}")
    if not (math.isfinite(cfg.correction_sigma_deg) and cfg.correction_sigma_deg >= 0.0):
        raise BudgetError(f'correction_sigma_deg must be >= 0, got {cfg.correction_sigma_deg}')
    if not (math.isfinite(cfg.sigma_floor_deg) and cfg.sigma_floor_deg >= 0.0):
        raise BudgetError(f'sigma_floor_deg must be >= 0, got {cfg.sigma_floor_deg}')
    if cfg.imu.noise_deg < 0.0:
        raise BudgetError(f'--imu: noise_deg is a 1-sigma, >= 0; got {cfg.imu.noise_deg}')
    cam = cfg.scene.camera
    if int(cam.width_px) * int(cam.height_px) > MAX_BUDGET_PIXELS:
        raise BudgetError(
            f'the scene camera has {cam.width_px} x {cam.height_px} pixels, more than the '
            f'{MAX_BUDGET_PIXELS} a budget renders; use a smaller (binned) camera'
        )
    return methods


def run_budget(
    cfg: BudgetConfig, progress=None, workers: int | None = 1, scheduler: str | None = None
) -> dict:
    """
    Run the budget and return it as a JSON-able dict.

    The Monte Carlo and the paired breakdown by source of the module docstring: one condition with
    everything declared, then one per declared source without it, on the same samples.
    ``workers=1`` without ``scheduler`` runs in this process; otherwise (condition, block of
    samples) tasks run on Dask distributed (:mod:`~polarization_compass.sweep_dask`), each with
    numba on one thread, giving the same statistics as an in-process run on one numba thread.

    Parameters
    ----------
    cfg : BudgetConfig
        The budget configuration.
    progress : callable, optional
        ``progress(text)``, called with each condition's name (``"all"``, ``"without <source>"``).
    workers : int or None, default 1
        Worker processes; 1 (without ``scheduler``) runs in this process, None = one per core on a
        Dask LocalCluster.
    scheduler : str, optional
        Address of an existing Dask scheduler (``"tcp://HOST:PORT"``).

    Returns
    -------
    dict
        ``scene``, ``samples``, ``tilt_max_deg``, ``imu`` (the MountingErrors fields), ``methods``,
        ``sources``, ``conditions`` (per condition and method: ``count``, ``ok``, ``share_not_ok``,
        ``rms_deg``, ``p95_deg``, ``max_deg`` of the heading error [deg] over the ok results, None
        without one; ``sigma_calibration`` = mean(err^2 / sigma^2), ``sigma_count``,
        ``sigma_band``: ``honest`` inside :data:`SIGMA_BAND`, ``overconfident`` above it (sigma too
        small: the flag the budget raises instead of hiding it), ``conservative`` below),
        ``breakdown`` (per method and source: ``rms_without_deg`` and ``contribution_deg`` =
        ``sqrt(max(0, RMS_all^2 - RMS_without^2))`` [deg]), ``correction`` (``mode``, the corrected
        ``methods``, the ``error_map``, the camera it was made for and whether that is the
        scene's), ``attitude_sigma_deg_level`` (the stated pitch/roll 1-sigma of a level camera)
        and ``sampling`` (how frames were drawn).

    Raises
    ------
    BudgetError
        When ``cfg.samples < 1``, a method name is not registered, ``correction`` or
        ``correction_sigma_deg`` is invalid, or the error map cannot be read.
    ErrorMapError
        When a Dask run cannot start (Dask missing, scheduler unreachable).

    """
    methods = check_config(cfg)
    fixed = corrected_methods(cfg, methods)
    samples = _samples(cfg)
    sources = declared_sources(cfg)
    conds = [('all', cfg)] + [(f'without {s}', without(cfg, s)) for s in sources]
    conditions = {}
    if workers == 1 and scheduler is None:
        for name, c in conds:
            if progress:
                progress(name)
            conditions[name] = _run_condition(c, samples, methods)
    else:
        conditions = _run_conditions_on_dask(conds, samples, methods, scheduler, workers, progress)
    breakdown = {}
    for m in methods:
        total = conditions['all'][m]['rms_deg']
        b = {}
        for s in sources:
            w = conditions[f'without {s}'][m]['rms_deg']
            contrib = None
            if total is not None and w is not None:
                contrib = math.sqrt(max(0.0, total**2 - w**2))
            b[s] = {'rms_without_deg': w, 'contribution_deg': contrib}
        breakdown[m] = b
    imu = {k: getattr(cfg.imu, k) for k in MountingErrors.FIELDS}
    correction = {'mode': cfg.correction, 'methods': fixed}
    if fixed:
        meta = _error_map(cfg.error_map).meta
        map_cam = (meta.get('scene') or {}).get('camera') if isinstance(meta, dict) else None
        correction.update(
            error_map=cfg.error_map or 'shipped',
            map_camera=map_cam,
            map_camera_is_scene_camera=bool(map_cam)
            and {k: map_cam.get(k) for k in map_cam}
            == {k: getattr(cfg.scene.camera, k, None) for k in map_cam},
            correction_sigma_deg=cfg.correction_sigma_deg,
        )
    return {
        'scene': cfg.scene.name,
        'samples': cfg.samples,
        'sigma_floor_deg': cfg.sigma_floor_deg,
        'tilt_max_deg': cfg.tilt_max_deg,
        'imu': imu,
        'methods': methods,
        'sources': sources,
        'conditions': conditions,
        'breakdown': breakdown,
        'correction': correction,
        'attitude_sigma_deg_level': list(cfg.imu.tilt_sigma_deg(0.0)),
        'sampling': {
            'bearing_deg': [0, 360],
            'tilt': f'|pitch| + |roll| <= {cfg.tilt_max_deg:g} deg',
            'sun': "the scene's",
            'seeds': 'scene seed per sample',
        },
    }


def plot_budget(result: dict, path) -> None:
    """
    Plot one panel per method: total RMS and each source's contribution.

    Horizontal bars, each panel on its own scale, titled with the method's RMS, p95, share not ok
    and sigma calibration; written as a PNG (matplotlib, Agg backend, 100 dpi).

    Parameters
    ----------
    result : dict
        The result of :func:`run_budget`.
    path : str or os.PathLike
        The PNG file to write.

    """
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    methods = result['methods']
    sources = result['sources']
    rows = ['total'] + sources
    fig, axes = plt.subplots(
        len(methods), 1, figsize=(7, 0.6 + (0.3 * len(rows) + 0.5) * len(methods)), squeeze=False
    )
    for ax, m in zip(axes[:, 0], methods):
        st = result['conditions']['all'][m]
        vals = [st['rms_deg']] + [result['breakdown'][m][s]['contribution_deg'] for s in sources]
        y = -np.arange(len(rows))
        ax.barh(y, [v or 0.0 for v in vals], color=['k'] + ['C0'] * len(sources))
        ax.set_yticks(y)
        ax.set_yticklabels(rows, fontsize=8)
        sig = st['sigma_calibration']
        title = (
            f'{m}: RMS {st["rms_deg"]:.3g} deg, p95 {st["p95_deg"]:.3g}, not ok '
            f'{st["share_not_ok"]:.0%}, '
            f'mean err^2/sigma^2 {"-" if sig is None else f"{sig:.3g}"}'
            if st['rms_deg'] is not None
            else f'{m}: no ok result ({st["share_not_ok"]:.0%} not ok)'
        )
        ax.set_title(title, fontsize=8, loc='left')
        ax.grid(axis='x', alpha=0.3)
        ax.tick_params(axis='x', labelsize=7)
    axes[-1, 0].set_xlabel(
        'heading error RMS (total) / contribution of the source (deg)', fontsize=8
    )
    fig.suptitle(
        f'error budget: {result["scene"]}, {result["samples"]} samples, '
        f'tilt <= {result["tilt_max_deg"]:g} deg',
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
