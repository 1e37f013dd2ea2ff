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
Accuracy against time: every method and accuracy knob over seeded random scenes per condition.

For each (condition, method, knob set) this measures the heading error over ``cfg.scenes`` seeded
random scenes (RMS, 95th percentile and max of |error|; axial methods' errors folded to (-90, 90]),
the time per estimate (median and 95th percentile, one core), the peak memory of one estimate and,
for the noisy conditions, the Cramer-Rao bound of the heading for the raw pixels that knob set
reads (:mod:`bench.crb`: the sampled pixels, each worth one superpixel after a superpixel demosaic
and up to 9/4 superpixels -- its 3 x 3 raw neighbourhood -- after a full-resolution one), so each
point can be compared with the physical limit.

Conditions
----------
``ideal_level``        Rayleigh sky (DoP_max 1), ideal sensor, level camera: the model error floor.
``noise_imx250``       Rayleigh, DoP_max 0.7, IMX250MZR-like sensor: mosaic, shot noise (~5000 e-
                       per pixel), read noise 2.3 e-, 12 bit, extinction ratio 100; both demosaics
                       (superpixel and full-resolution). Level camera.
``tilted``             Rayleigh, ideal sensor, camera tilted (|pitch| + |roll| <= 20 deg), no
                       correction.
``tilted_corrected``   the same scenes, headings corrected with the shipped error map
                       (:class:`polarization_compass.correction.TiltCorrector`, true pitch and
                       roll), both ``invert`` and ``subtract`` corrections; skipped when no map is
                       shipped. A prior bearing 5 deg off (an IMU yaw) resolves the 180 deg
                       ambiguity first, as in the nodes.
``tilted_tilt_aware``  the same scenes, ``tilt_aware`` given the true pitch and roll.
                       (``tilt_aware`` runs in every condition except
                       ``tilted``/``tilted_corrected``, always given the true pitch and roll: 0, 0
                       in the level conditions.)
``bdl_sky``            Berry-Dennis-Lee neutral-point sky (separation 18 deg, DoP_max 0.75), ideal
                       sensor, level.
``half_occluded``      ideal Rayleigh, level, half of the image masked by a half-plane through the
                       centre at a random angle (asymmetric about the solar meridian). ``sm_asm``
                       and ``symmetry`` refuse about a fifth of these scenes (status
                       ``insufficient_coverage``, counted in ``fails``: the meridian lies near the
                       occluder's edge); errors are over the rest.
``eight_bit``          as ``noise_imx250`` but quantised to 8 bit.

Scenes: sun azimuth uniform in [0, 360), sun altitude uniform in [10, 60] deg ([10, 50] deg for the
tilted conditions: the paper's range and the shipped error map's domain), camera bearing uniform in
[0, 360); seeds are a function of (condition, scene index), so every method sees the same scenes.

"""

from __future__ import annotations

from dataclasses import dataclass, field
import hashlib
import math
import sys
import time
import traceback

import numpy as np
from polarization_compass.budget_config import published_sigma_floor_deg
from polarization_compass.camera import CameraModel, PixelSelection
from polarization_compass.conventions import CameraAttitude, fold_axial_deg, wrap_180_deg
from polarization_compass.estimators import registry
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene

from . import crb as crb_mod
from .common import (
    error_stats,
    optional_import,
    peak_memory,
    single_core,
    timing_stats,
    Unavailable,
)
from .simulator import ALL_EFFECTS as ALL_SENSOR_EFFECTS  # noqa: E402
from .simulator import NOISE_ELECTRONS

#: The smallest yaw sigma heading_estimator publishes (its ``sigma_floor_deg`` default): the sigma
#: calibration below uses what a robot would receive, ``max(sigma, floor)``.
SIGMA_FLOOR_DEG = published_sigma_floor_deg()

NOISE_DOP_MAX = 0.7
TILT_LIMIT_DEG = 20.0
#: An estimate slower than this (s) is timed once per scene instead of ``cfg.repeats`` times.
SLOW_ESTIMATE_S = 0.25


def condition_methods(cond: Condition, methods) -> list[str]:
    """Return those of ``methods`` that run in a condition (``cond.methods``: all, level, tilt)."""
    tilt = set(registry.tilt_methods())
    keep = {'all': lambda m: True, 'level': lambda m: m not in tilt, 'tilt': lambda m: m in tilt}
    return [m for m in methods if keep[cond.methods](m)]


@dataclass
class Condition:
    name: str
    description: str
    sky: dict = field(default_factory=lambda: {'model': 'rayleigh', 'dop_max': 1.0})
    sensor_bits: int | None = None  # None: ideal sensor; else all effects with this quantisation
    tilted: bool = False
    give_tilt: bool = False  # pass the true pitch/roll in the observation
    correct: bool = False  # correct with an error map
    occlude: bool = False
    # which methods run: 'all'; 'level', those that do not read the tilt; 'tilt', those that do
    # (registry.tilt_methods(): the estimator classes' needs_tilt)
    methods: str = 'all'
    scene: dict = field(default_factory=dict)  # issue 16: scene changes (atmosphere, optics)
    calibration: dict | None = None  # issue 16: sensor.calibration (sensor conditions)
    mounting: dict | None = None  # issue 16: motion.MountingErrors of the tilt given


CONDITIONS = {
    c.name: c
    for c in (
        Condition('ideal_level', 'Rayleigh (DoP_max 1), ideal sensor, level camera'),
        Condition(
            'noise_imx250',
            'Rayleigh (DoP_max 0.7), IMX250MZR-like sensor (5000 e-, 2.3 e- read noise, 12 bit, '
            'ER 100), level',
            sky={'model': 'rayleigh', 'dop_max': NOISE_DOP_MAX},
            sensor_bits=12,
        ),
        Condition(
            'tilted',
            f'Rayleigh, ideal sensor, tilted |pitch|+|roll| <= {TILT_LIMIT_DEG:g} deg, '
            'uncorrected',
            tilted=True,
            methods='level',
        ),
        Condition(
            'tilted_corrected',
            "as 'tilted', headings corrected with an error map",
            tilted=True,
            correct=True,
            methods='level',
        ),
        Condition(
            'tilted_tilt_aware',
            "as 'tilted', tilt_aware given the true pitch and roll",
            tilted=True,
            give_tilt=True,
            methods='tilt',
        ),
        Condition(
            'bdl_sky',
            'Berry-Dennis-Lee sky (separation 18 deg, DoP_max 0.75), ideal sensor, level',
            sky={'model': 'berry_dennis_lee', 'separation_deg': 18.0, 'dop_max': 0.75},
        ),
        Condition(
            'half_occluded',
            'ideal Rayleigh, level, half the image masked (half-plane at a random angle)',
            occlude=True,
        ),
        Condition(
            'eight_bit',
            'as noise_imx250 but 8-bit quantisation',
            sky={'model': 'rayleigh', 'dop_max': NOISE_DOP_MAX},
            sensor_bits=8,
        ),
        # issue 16: real skies and sensors (atmosphere.py, optics.py, sensor calibration,
        # motion.MountingErrors)
        Condition(
            'clouds_30',
            'Rayleigh (DoP_max 0.7) with CIE clear-sky radiance, 30 % broken clouds (optical '
            'thickness 3), ideal sensor, level',
            sky={'model': 'rayleigh', 'dop_max': NOISE_DOP_MAX},
            scene={
                'radiance': {'model': 'cie_clear'},
                'atmosphere': {'clouds': {'coverage': 0.3, 'optical_thickness': 3.0}},
            },
        ),
        Condition(
            'clouds_70',
            'as clouds_30 with 70 % cover',
            sky={'model': 'rayleigh', 'dop_max': NOISE_DOP_MAX},
            scene={
                'radiance': {'model': 'cie_clear'},
                'atmosphere': {'clouds': {'coverage': 0.7, 'optical_thickness': 3.0}},
            },
        ),
        Condition(
            'overcast',
            'as clouds_30 under a uniform overcast of optical thickness 2',
            sky={'model': 'rayleigh', 'dop_max': NOISE_DOP_MAX},
            scene={
                'radiance': {'model': 'cie_clear'},
                'atmosphere': {'clouds': {'coverage': 1.0, 'optical_thickness': 2.0}},
            },
        ),
        Condition(
            'haze',
            'Rayleigh (DoP_max 0.7), haze of turbidity 5 (DoP x 0.4, Preetham radiance), ideal '
            'sensor',
            sky={'model': 'rayleigh', 'dop_max': NOISE_DOP_MAX},
            scene={'atmosphere': {'haze': {'turbidity': 5.0}}},
        ),
        Condition(
            'glare_flare',
            'Rayleigh (DoP_max 0.7), sun glare, flare ghosts and cos4 vignetting, ideal sensor',
            sky={'model': 'rayleigh', 'dop_max': NOISE_DOP_MAX},
            scene={'optics': {'sun': {}, 'flare': {}, 'vignetting': {'law': 'cos4'}}},
        ),
        Condition(
            'calibration',
            'as noise_imx250 plus DoFP calibration errors (polarizer angle 1 deg, gain 1 %, '
            'crosstalk 1 %)',
            sky={'model': 'rayleigh', 'dop_max': NOISE_DOP_MAX},
            sensor_bits=12,
            calibration={'angle_error_deg': 1.0, 'gain_rms': 0.01, 'crosstalk': 0.01},
        ),
        Condition(
            'boresight',
            "as 'tilted_tilt_aware' with a 1 deg camera-to-IMU boresight misalignment (pitch and "
            'roll)',
            tilted=True,
            give_tilt=True,
            methods='tilt',
            mounting={'boresight_pitch_deg': 1.0, 'boresight_roll_deg': 1.0},
        ),
    )
}


# ------------------------------------------------------------------------------------------------
# Knob sets: (label, estimator knobs, demosaic for sensor conditions)
# ------------------------------------------------------------------------------------------------
def knob_sets(method: str, level: str, sensor: bool) -> list[tuple[str, dict, str | None]]:
    """
    Return the accuracy knobs swept for a method; ``level``: quick | full | tiny.

    The sets follow the knobs the method declares (:func:`registry.knob_names`), not its name, so a
    new method gets its sets without an edit here: a ``window_px`` method sweeps its window; a
    ``stride`` method its stride (and its defaults at ``full``), plus centred regions when it has
    ``region`` and no ``disc_fraction`` (a disc method needs the whole sky disc) and half the disc
    when it has ``disc_fraction``; a method with neither window nor stride runs its defaults.
    """
    knobs_of = registry.knob_names(method)
    strides = {'tiny': (4,), 'quick': (4, 16), 'full': (2, 4, 8, 16)}[level]
    out: list[tuple[str, dict, str | None]] = []
    demosaics = (
        [None]
        if not sensor
        else (['superpixel'] if level == 'tiny' else ['superpixel', 'bilinear'])
    )
    for dm in demosaics:
        tag = (
            ''
            if dm is None
            else (', superpixel demosaic' if dm == 'superpixel' else ', full-res demosaic')
        )
        if 'window_px' in knobs_of:
            windows = {'tiny': (9,), 'quick': (9, 33), 'full': (5, 9, 17, 33, 65, 129)}[level]
            out += [(f'window {w} px{tag}', {'window_px': w}, dm) for w in windows]
            continue
        if 'stride' not in knobs_of:
            out.append((f'default{tag}', {}, dm))
            continue
        if level == 'full':  # the method's defaults (often every pixel: slow, so full mode only)
            out.append((f'default{tag}', {}, dm))
        out += [
            (f'stride {s}{tag}', {'stride': s}, dm)
            for s in strides
            if not (s == 2 and dm == 'superpixel')
        ]
        disc = 'disc_fraction' in knobs_of
        if 'region' in knobs_of and not disc and level != 'tiny':
            regions = {'quick': (512,), 'full': (256, 512, 1024)}[level]
            out += [
                (
                    f'region {r}x{r} centre, stride 4{tag}',
                    {'region': _centre_region(r), 'stride': 4},
                    dm,
                )
                for r in regions
            ]
        if disc and level == 'full':
            out.append((f'disc_fraction 0.5{tag}', {'disc_fraction': 0.5}, dm))
    return out


def _centre_region(size_px: int, camera: CameraModel | None = None):
    cam = camera or CameraModel()
    w = min(size_px, cam.width_px)
    h = min(size_px, cam.height_px)
    return ((cam.width_px - w) // 2 + 1, (cam.height_px - h) // 2 + 1, w, h)


def crb_selection(knobs: dict, demosaic: str | None, camera: CameraModel, default_stride: int = 1):
    """
    Return the samples a knob set reads, as a PixelSelection, for the Cramer-Rao bound.

    ``stride`` is in sensor pixels (estimators' convention); on a superpixel image (grid spacing 2
    px) it becomes ``max(1, round(stride / 2))`` superpixels, i.e. a sample spacing of 2, 4, ...
    px.
    """
    stride = max(1, int(knobs.get('stride', default_stride) or 1))
    if demosaic == 'superpixel':
        stride = 2 * max(1, int(round(stride / 2)))
    if 'window_px' in knobs:
        w = int(knobs['window_px'])
        x0, y0, ww, hh = _centre_region(w, camera)
        return PixelSelection.rect(x0, y0, ww, hh, stride=stride)
    if knobs.get('region') is not None:
        x0, y0, w, h = knobs['region']
        return PixelSelection.rect(x0, y0, w, h, stride=stride)
    return PixelSelection.strided(stride)


# ------------------------------------------------------------------------------------------------
# Scenes
# ------------------------------------------------------------------------------------------------
def _seed(*parts) -> int:
    h = hashlib.blake2b(':'.join(map(str, parts)).encode(), digest_size=8).digest()
    return int.from_bytes(h, 'little') & 0x7FFFFFFF


def sample_scene(condition: Condition, index: int) -> dict:
    """Seeded random sun, attitude, noise seed and occluder angle for one scene."""
    base = condition.name.replace('_corrected', '').replace('_tilt_aware', '')
    rng = np.random.default_rng(_seed('scene', base, index))
    top = (
        50.0 if condition.tilted else 60.0
    )  # tilted: the paper's range (and the error map's domain)
    sun = SunDirection(float(rng.uniform(0, 360)), float(rng.uniform(10, top)))
    bearing = float(rng.uniform(0, 360))
    pitch = roll = 0.0
    if condition.tilted:
        pitch = float(rng.uniform(-TILT_LIMIT_DEG, TILT_LIMIT_DEG))
        lim = TILT_LIMIT_DEG - abs(pitch)
        roll = float(rng.uniform(-lim, lim))
    return {
        'sun': sun,
        'attitude': CameraAttitude(bearing, pitch, roll),
        'noise_seed': _seed('noise', base, index),
        'occluder_angle_rad': float(rng.uniform(0, 2 * math.pi)),
    }


def occlusion_mask(x_px, y_px, camera: CameraModel, angle_rad: float) -> np.ndarray:
    """Return True for pixels on one side of a line through the image centre at ``angle_rad``."""
    u = np.asarray(x_px, dtype=float) - camera.cx_px
    v = np.asarray(y_px, dtype=float) - camera.cy_px
    return (u * math.cos(angle_rad) + v * math.sin(angle_rad)) >= 0.0


def heading_error_deg(result, true_psi_deg: float) -> float | None:
    """Estimated minus true psi: folded mod 180 for axial results, wrapped mod 360 otherwise."""
    if result is None or not result.ok or result.psi_deg is None:
        return None
    d = result.psi_deg - true_psi_deg
    return float(fold_axial_deg(d)) if result.axial else float(wrap_180_deg(d))


# ------------------------------------------------------------------------------------------------
# Demosaic timing (shared with bench.peers)
# ------------------------------------------------------------------------------------------------
def time_demosaic_only(camera: CameraModel, repeats: int) -> dict:
    """
    Time the raw mosaic -> AoP/DoP/valid demosaic alone, superpixel and full resolution.

    Raw mosaic -> AoP/DoP/valid (``demosaic.polarization_from_mosaic``), superpixel and full
    resolution, single core.
    """
    dm = optional_import('polarization_compass.demosaic')
    from . import simulator
    from .common import time_calls

    scene = Scene(camera=camera, sensor=simulator.sensor_config(ALL_SENSOR_EFFECTS, 'superpixel'))
    frame = Renderer(scene).render(
        attitude=CameraAttitude(40, 0, 0), sun=SunDirection(135, 35), seed=1
    )
    if frame.mosaic is None:
        raise Unavailable('render produced no mosaic')
    out = {}
    for key, method in (
        ('demosaic_superpixel_aop_dop', 'superpixel'),
        ('demosaic_full_resolution_aop_dop', 'bilinear'),
    ):
        with single_core():
            out[key] = timing_stats(
                time_calls(
                    lambda m=method: dm.polarization_from_mosaic(frame.mosaic, method=m), repeats
                )
            )
    return out


# ------------------------------------------------------------------------------------------------
# The sweep
# ------------------------------------------------------------------------------------------------
class _Cell:
    """Accumulates one (condition, method, knob set)."""

    def __init__(self, condition, method, label, knobs, demosaic):
        self.condition, self.method, self.label, self.knobs, self.demosaic = (
            condition,
            method,
            label,
            knobs,
            demosaic,
        )
        self.errors: list[float] = []
        self.failures = 0
        self.statuses: dict = {}
        self.times: list[float] = []
        self.pixels: list[int] = []
        self.sigmas: list[float] = []
        self.z2: list[float] = []  # (error / max(sigma, floor))^2 of ok results with a sigma
        self.crbs: list[float] = []
        self.memory = None
        self.status = 'ok'
        self.estimator = None
        self.corrector = None
        self.warm = False

    def to_json(self) -> dict:
        e = error_stats(self.errors, self.failures)
        t = timing_stats(self.times)
        crb = float(np.sqrt(np.mean(np.square(self.crbs)))) if self.crbs else None
        return {
            'condition': self.condition,
            'method': self.method,
            'knobs_label': self.label,
            'knobs': {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.knobs.items()},
            'demosaic': self.demosaic,
            'status': self.status,
            'error': e,
            'time': t,
            'memory': self.memory,
            'pixels_used_median': int(np.median(self.pixels)) if self.pixels else None,
            'sigma_reported_rms_deg': float(np.sqrt(np.mean(np.square(self.sigmas))))
            if self.sigmas
            else None,
            # issue 16: mean(err^2 / sigma^2), 1 for an honest sigma, and the share of results
            # more than 5 sigma off (a "wrong ok"), with the published floor applied
            'sigma_floor_deg': SIGMA_FLOOR_DEG,
            'sigma_calibration': float(np.mean(self.z2)) if self.z2 else None,
            'beyond_5_sigma': int(np.sum(np.asarray(self.z2) > 25.0)) if self.z2 else None,
            'crb_rms_deg': crb,
            'rms_over_crb': (e['rms_deg'] / crb) if (crb and e['rms_deg'] is not None) else None,
            'statuses': self.statuses,
        }


def _methods(cfg):
    est = optional_import('polarization_compass.estimators')
    names = list(est.estimator_names())
    if not names:
        raise Unavailable('no estimators registered yet')
    if cfg.methods:
        names = [n for n in names if n in cfg.methods]
    return est, names


def error_map_path(cfg):
    """
    Return the error map used by ``tilted_corrected``.

    The error map for ``tilted_corrected``: ``cfg.error_map`` / ``$BENCH_ERROR_MAP``, else the
    shipped one.
    """
    import os
    from pathlib import Path

    given = getattr(cfg, 'error_map', None) or os.environ.get('BENCH_ERROR_MAP')
    if given:
        return Path(given)
    from polarization_compass.correction import default_map_path

    return default_map_path()


def _map_corrector(method: str, mode: str, path):
    """
    Return a result corrector that uses the error map at ``path``.

    ``fn(result, obs, scene) -> result`` correcting with the error map at ``path``, or raises.
    """
    from polarization_compass.correction import TiltCorrector
    from polarization_compass.estimators.base import HeadingResult, Status

    if not path.is_file():
        raise Unavailable(f'no error map at {path}')
    corrector = TiltCorrector.from_file(path, method=method)

    def fn(res, obs, s):
        if not res.ok:
            return res
        att = s['attitude']
        c = corrector.correct(
            res.psi_deg, obs.sun_altitude_deg, att.pitch_deg, att.roll_deg, mode=mode
        )
        if not c.ok or c.psi_deg is None:
            return HeadingResult.failed(
                res.method,
                Status.OUT_OF_DOMAIN,
                f'correction {c.status.value}: {c.reason}',
                res.pixels,
            )
        return HeadingResult.from_psi(
            res.method,
            c.psi_deg,
            obs.sun_azimuth_deg,
            res.sigma_deg or 0.0,
            res.pixels,
            res.quality,
            res.axial,
        )

    return fn


def run(cfg) -> dict:
    est_mod, methods = _methods(cfg)
    map_path = None
    from polarization_compass.estimators.base import Observation

    level = 'tiny' if cfg.tiny else cfg.knob_sets
    camera = CameraModel(width_px=192, height_px=160) if cfg.tiny else CameraModel()
    conds = [CONDITIONS[c] for c in (cfg.conditions or CONDITIONS)]
    cells: list[_Cell] = []
    skipped = []
    t_start = time.perf_counter()
    for cond in conds:
        sensor = cond.sensor_bits is not None
        cond_methods = condition_methods(cond, methods)
        if cond.correct:
            try:
                map_path = _checked_map_path(cfg)
            except Unavailable as exc:
                skipped.append({'condition': cond.name, 'reason': str(exc)})
                continue
        try:
            base_scene = _base_scene(cond, camera, sensor)
        except Exception as exc:  # noqa: BLE001
            skipped.append({'condition': cond.name, 'reason': f'{type(exc).__name__}: {exc}'})
            continue
        cond_cells = _condition_cells(cond, cond_methods, est_mod, level, sensor, camera, map_path)
        cells.extend(cond_cells)
        t_cond = time.perf_counter()
        _run_scenes(cfg, cond, cond_cells, base_scene, camera, sensor, Observation)
        if not cfg.tiny:
            print(
                f'    accuracy: {cond.name}: {len(cond_cells)} configurations x {cfg.scenes} '
                'scenes in '
                f'{time.perf_counter() - t_cond:.0f} s',
                file=sys.stderr,
                flush=True,
            )
    return _result(cfg, conds, skipped, camera, cells, t_start)


def _checked_map_path(cfg):
    """Return the error map of a corrected condition, or raise Unavailable without one."""
    optional_import('polarization_compass.correction')
    map_path = error_map_path(cfg)
    if not map_path.is_file():
        raise Unavailable(f'no error map at {map_path}')
    return map_path


def _base_scene(cond: Condition, camera: CameraModel, sensor: bool):
    """Return the scene of ``cond`` before sampling (with its sensor model, if any)."""
    base_scene = Scene(camera=camera, sky=dict(cond.sky), seed=0).replace(**cond.scene)
    if sensor:
        from . import simulator

        scfg = simulator.sensor_config(ALL_SENSOR_EFFECTS, 'superpixel', bits=cond.sensor_bits)
        if cond.calibration:
            scfg['calibration'] = dict(cond.calibration)
        base_scene = base_scene.replace(sensor=scfg)
        Renderer(base_scene)  # fails early if the sensor code is not there yet
    return base_scene


def _condition_cells(cond, cond_methods, est_mod, level, sensor, camera, map_path) -> list[_Cell]:
    """Return the cells of ``cond``: one per method, knob set and correction mode."""
    cond_cells = []
    for m in cond_methods:
        for label, knobs, dm in knob_sets(m, level, sensor):
            if 'region' in knobs:
                knobs = dict(knobs, region=_centre_region(knobs['region'][2], camera))
            for mode in ('invert', 'subtract') if cond.correct else (None,):
                c = _Cell(
                    cond.name, m, label + (f', correction {mode}' if mode else ''), knobs, dm
                )
                try:
                    c.estimator = est_mod.make_estimator(m, **knobs)
                    if mode:
                        c.corrector = _map_corrector(m, mode, map_path)
                # a knob this method does not have, no map entry
                except Exception as exc:  # noqa: BLE001
                    c.status = f'unavailable: {type(exc).__name__}: {exc}'
                    c.estimator = None
                cond_cells.append(c)
    return cond_cells


def _run_scenes(cfg, cond, cond_cells, base_scene, camera, sensor, Observation):
    """Render the sampled scenes of ``cond`` and run every live cell on each."""
    renderers: dict = {}
    for k in range(int(cfg.scenes)):
        s = sample_scene(cond, k)
        frames: dict = {}
        for c in cond_cells:
            if c.estimator is None:
                continue
            try:
                frame = _frame_for(c, s, sensor, base_scene, camera, renderers, frames)
                _run_cell(c, frame, s, cond, camera, Observation, cfg)
            # one broken method must not stop the suite
            except Exception as exc:  # noqa: BLE001
                c.status = f'failed: {type(exc).__name__}: {exc}'
                c.estimator = None
                c.traceback = traceback.format_exc(limit=3)


def _frame_for(c: _Cell, s, sensor, base_scene, camera, renderers: dict, frames: dict):
    """Return the frame of scene ``s`` that cell ``c`` needs, rendering it once per scene."""
    if sensor:
        key = ('full', c.demosaic)
        if key not in renderers:
            sc = base_scene.replace(sensor=dict(base_scene.sensor, demosaic=c.demosaic))
            renderers[key] = Renderer(sc, pixels=PixelSelection.full())
    else:
        key = c.estimator.pixels_needed(camera)
        if key not in renderers:
            renderers[key] = Renderer(base_scene, pixels=key)
    if key not in frames:
        frames[key] = renderers[key].render(
            attitude=s['attitude'], sun=s['sun'], seed=s['noise_seed']
        )
    return frames[key]


def _result(cfg, conds, skipped, camera: CameraModel, cells: list[_Cell], t_start: float) -> dict:
    """Return the group's JSON: the set-up, the skipped conditions and the cells."""
    return {
        'conditions': {c.name: c.description for c in conds},
        'skipped_conditions': skipped,
        'scenes_per_condition': int(cfg.scenes),
        'repeats_per_scene': int(cfg.repeats),
        'camera': {
            'model': camera.model,
            'width_px': camera.width_px,
            'height_px': camera.height_px,
        },
        'noise_model': {'electrons_per_pixel': NOISE_ELECTRONS, 'dop_max': NOISE_DOP_MAX},
        'scene_sampling': {
            'sun_azimuth_deg': [0, 360],
            'sun_altitude_deg': [10, 60],
            'sun_altitude_deg_tilted': [10, 50],
            'bearing_deg': [0, 360],
            'tilt': f'|pitch|+|roll| <= {TILT_LIMIT_DEG:g} deg (tilted conditions)',
        },
        'cells': [c.to_json() for c in cells],
        'elapsed_s': time.perf_counter() - t_start,
    }


#: Prior bearing error in ``tilted_corrected`` (deg): a magnetometer-grade IMU yaw, as the
#: simulated IMU's default bias. The correction depends on which of the two solar-meridian branches
#: the heading is on (the error map is not 180 deg periodic under tilt), so, as in the nodes
#: (``prior_source: imu``), a prior resolves the branch before correcting; an unresolved heading
#: corrected on the wrong branch is off by up to a degree even with a perfect map.
PRIOR_ERROR_DEG = 5.0


def _observation(frame, s, cond, camera, Observation, method=''):
    obs = Observation.from_frame(frame, camera=camera)
    if cond.correct:
        obs.prior_bearing_deg = (s['attitude'].bearing_deg + PRIOR_ERROR_DEG) % 360.0
    if cond.give_tilt or method in registry.tilt_methods():  # always given the true pitch and roll
        obs.pitch_deg = s['attitude'].pitch_deg
        obs.roll_deg = s['attitude'].roll_deg
        if cond.mounting:  # ... or what a misaligned IMU says
            from polarization_compass.motion import MountingErrors

            seen = MountingErrors(**cond.mounting).measured_attitude(s['attitude'], np.zeros(3))
            obs.pitch_deg, obs.roll_deg = seen.pitch_deg, seen.roll_deg
    if cond.occlude:
        keep = occlusion_mask(frame.x_px, frame.y_px, camera, s['occluder_angle_rad'])
        obs.valid = np.asarray(frame.valid) & keep
    return obs


def _run_cell(c: _Cell, frame, s, cond, camera, Observation, cfg):
    obs = _observation(frame, s, cond, camera, Observation, c.method)
    est = c.estimator
    corrector = c.corrector

    def once():
        r = est.estimate(obs)
        if corrector is not None:
            r = corrector(r, obs, s)
        return r

    with single_core():
        if not c.warm:
            once()  # compile / caches: not timed
            c.warm = True
            c.memory = peak_memory(once)
        res = None
        for k in range(max(1, int(cfg.repeats))):
            t0 = time.perf_counter()
            res = once()
            c.times.append(time.perf_counter() - t0)
            if c.times[-1] > (
                SLOW_ESTIMATE_S if cfg.mode == 'full' else 0.05
            ):  # slow: once per scene
                break
    true_psi = frame.psi_deg
    err = heading_error_deg(res, true_psi)
    st = getattr(res.status, 'value', str(res.status))
    c.statuses[st] = c.statuses.get(st, 0) + 1
    if err is None:
        c.failures += 1
    else:
        c.errors.append(err)
        c.pixels.append(int(res.pixels))
        if res.sigma_deg is not None:
            c.sigmas.append(float(res.sigma_deg))
            c.z2.append((err / max(float(res.sigma_deg), SIGMA_FLOOR_DEG)) ** 2)
    if cond.sensor_bits is not None:
        eff = getattr(est, 'knobs', None)
        eff = eff if isinstance(eff, dict) else c.knobs  # the estimator's knobs incl. its defaults
        sel = crb_selection(eff, c.demosaic, camera)
        min_dop = float(eff.get('min_dop', 0.0) or 0.0)
        extra = None
        if min_dop > 0:
            from polarization_compass.camera import select_pixels

            from .crb import aop_and_derivative

            px = select_pixels(camera, sel)
            _, dop, *_ = aop_and_derivative(
                px.rays_cam,
                s['attitude'].bearing_deg,
                s['attitude'].pitch_deg,
                s['attitude'].roll_deg,
                s['sun'].azimuth_deg,
                s['sun'].altitude_deg,
                NOISE_DOP_MAX,
            )
            extra = dop * (99.0 / 101.0) >= min_dop  # the sensor measures d * DoP (ER 100)
        b = crb_mod.crb_for_selection(
            camera,
            sel,
            s['attitude'].bearing_deg,
            s['attitude'].pitch_deg,
            s['attitude'].roll_deg,
            s['sun'].azimuth_deg,
            s['sun'].altitude_deg,
            NOISE_ELECTRONS,
            NOISE_DOP_MAX,
            extinction_ratio=100.0,
            extra_mask=extra,
            sample_weight=crb_mod.raw_pixel_weight(sel.stride, c.demosaic),
        )
        if b['crb_deg'] is not None:
            c.crbs.append(b['crb_deg'])
