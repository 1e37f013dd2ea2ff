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
The error budget: what heading accuracy a scene gives, per method, and what each effect costs.

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

The configuration (:class:`~polarization_compass.budget_config.BudgetConfig`), the sources and
their switches are :mod:`polarization_compass.budget_config`'s.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from .budget_config import BudgetConfig, BudgetError, check_config, declared_sources, without
from .conventions import CameraAttitude, fold_axial_deg, wrap_180_deg
from .motion import MountingErrors

__all__ = [
    'SIGMA_BAND',
    'corrected_methods',
    'run_budget',
    'plot_budget',
]

#: The band of ``mean(err^2 / sigma^2)`` taken as honest. The mean of N chi^2_1 draws has a
#: standard deviation of sqrt(2 / N) (0.14 at N = 100), but a budget's errors are neither Gaussian
#: nor independent (one fixed calibration pattern, one cloud field per frame), hence the wide band.
SIGMA_BAND = (0.3, 3.0)


def _samples(cfg: BudgetConfig):
    """
    Draw each sample's (bearing, pitch, roll, scene seed, IMU normals), seeded by the scene only.

    Pitch and roll are drawn with ``|pitch| + |roll| <= 1``; the condition scales them by
    ``tilt_max_deg``.
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
    Return the raw results of some samples of one condition, run on a Dask worker.

    numba runs on one thread there, so the results equal an in-process run's.
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
