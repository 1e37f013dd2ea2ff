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
Issue 14: what the real-sky robustness costs, per method.

For each method, on one core: the estimate alone (and, for least_squares/tilt_aware, with the
robust refit ``outlier_deg`` 15 that ``estimate`` turns on for real images), and the whole-sky
check that ``estimate`` adds on real images (:func:`polarization_compass.skyfit.assess_result`:
sampling the usable sky, the misfit at the estimate, the 8-sector jackknife sigma and the 180 deg
side vote; plus one shared ``sample_sky`` per frame); and the polarizer check
(:class:`polarization_compass.pipeline.PolarizerMonitor`, what the node runs every
``polarizer_check_every``-th image) on a full-size raw mosaic.

Frames: the real ``sunny.jpg`` (test/data/real-sky, 2048 x 2048 Stokes planes, fisheye) through
``estimate``'s own observation builder
(:func:`polarization_compass.pipeline.real_image.real_observation`), and a simulated
``imx250mzr_noisy`` mosaic for the monitor.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
import time

from .common import optional_import, single_core, timing_stats, Unavailable

ROOT = Path(__file__).resolve().parent.parent
METHODS = ('zenith', 'sm_asm', 'symmetry', 'least_squares', 'tilt_aware')


def _real_sky():
    p = ROOT / 'test' / 'real_sky.py'
    if not (ROOT / 'test' / 'data' / 'real-sky' / 'sunny.jpg').exists():
        raise Unavailable('test/data/real-sky/sunny.jpg is not there')
    spec = importlib.util.spec_from_file_location('real_sky_bench', p)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def run(cfg) -> dict:
    optional_import('polarization_compass.skyfit')
    from polarization_compass.estimators import estimator_names
    from polarization_compass.pipeline.real_image import real_observation
    from polarization_compass.pipeline.sampling import observation_sky_sample
    from polarization_compass.real_input import PolarizationInput

    R = _real_sky()
    i, q, u = R.read_quadrants('sunny')
    step = 4 if cfg.tiny else 1
    inp = PolarizationInput(
        'stokes', 'sunny.jpg', stokes=(i[::step, ::step], q[::step, ::step], u[::step, ::step])
    )
    cf = _camera_file(R, step)
    alt = R.sun_altitude_deg('sunny')
    repeats = max(1, int(cfg.repeats))
    obs, _ = real_observation(inp, cf, 0.0, alt, pitch=0.0, roll=0.0)
    with single_core():
        t_sample = []
        for _ in range(repeats + 1):
            t0 = time.perf_counter()
            sample = observation_sky_sample(obs)
            t_sample.append(time.perf_counter() - t0)
        rows = [
            _method_row(m, obs, sample, alt, repeats)
            for m in METHODS
            if m in estimator_names() and (not cfg.methods or m in cfg.methods)
        ]
        monitor = _monitor(cfg, repeats)
    return {
        'frame': 'sunny.jpg (real, 2048 x 2048 Stokes)'
        if step == 1
        else 'sunny.jpg decimated (tiny)',
        'pixels': int(obs.valid.size),
        'sample_sky': timing_stats(t_sample[1:]),
        'rows': rows,
        'polarizer_monitor': monitor,
        'threads': 1,
        'note': 'sky_check = assess_result per method (misfit, jackknife sigma, side vote) after '
        'one shared '
        'sample_sky per frame; polarizer_monitor = one check on a full-size mosaic (node, every '
        'N-th image)',
    }


def _camera_file(R, step: int):
    """Read the frames' camera file, for planes decimated by ``step`` (the same lens, scaled)."""
    import tempfile

    from polarization_compass.camera_file import load_camera_yaml

    with tempfile.TemporaryDirectory() as d:
        y = Path(d) / 'cam.yaml'
        text = R.camera_yaml_text()
        if step > 1:  # the decimated planes: the same lens at 1/step scale
            import math

            f = R.RADIUS_90_PX / (math.pi / 2) / step
            cx, cy = R.CENTRE_PX[0] / step, R.CENTRE_PX[1] / step
            text = text.replace('image_width: 2048', f'image_width: {2048 // step}').replace(
                'image_height: 2048', f'image_height: {2048 // step}'
            )
            text = text.split('camera_matrix')[0] + (
                f'camera_matrix: {{rows: 3, cols: 3, data: [{f}, 0, {cx}, 0, {f}, {cy}, 0, 0, '
                f'1]}}\n' + 'distortion_model' + text.split('distortion_model', 1)[1]
            )
        y.write_text(text)
        return load_camera_yaml(y)


def _method_row(m: str, obs, sample, alt: float, repeats: int) -> dict:
    """Time one method: its estimate, its whole-sky check and, if it has one, its robust refit."""
    from polarization_compass.estimators import make_estimator
    from polarization_compass.pipeline.methods import REAL_SKY_KNOBS
    from polarization_compass.skyfit_assess import assess_result

    est = make_estimator(m)
    assess_result(est.estimate(obs), sample, alt, 0.0, 0.0)  # warm-up
    t_est, t_chk, statuses = [], [], {}
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = est.estimate(obs)
        t1 = time.perf_counter()
        out = assess_result(res, sample, alt, 0.0, 0.0)
        t2 = time.perf_counter()
        t_est.append(t1 - t0)
        t_chk.append(t2 - t1)
        statuses[out.status.value] = statuses.get(out.status.value, 0) + 1
    row = {
        'method': m,
        'estimate': timing_stats(t_est),
        'sky_check': timing_stats(t_chk),
        'statuses': statuses,
    }
    if 'outlier_deg' in est.knobs:  # the robust refit estimate turns on for real images
        rob = make_estimator(m, **REAL_SKY_KNOBS)
        rob.estimate(obs)
        t_rob = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            rob.estimate(obs)
            t_rob.append(time.perf_counter() - t0)
        row['estimate_robust_refit'] = timing_stats(t_rob)
    return row


def _monitor(cfg, repeats) -> dict:
    from polarization_compass.camera import CameraModel
    from polarization_compass.conventions import CameraAttitude
    from polarization_compass.mosaic import parse_layout
    from polarization_compass.pipeline import PolarizerMonitor
    from polarization_compass.render import Renderer, SunDirection
    from polarization_compass.scene_load import load_scene

    scene = load_scene(str(ROOT / 'config' / 'scenes' / 'imx250mzr_noisy.yaml'))
    if cfg.tiny:
        scene = scene.replace(camera=CameraModel(width_px=192, height_px=160))
    f = Renderer(scene).render(
        attitude=CameraAttitude(40.0, 0.0, 0.0), sun=SunDirection(135.0, 35.0), seed=3
    )
    if f.mosaic is None:
        raise Unavailable('the scene rendered no mosaic')
    mon = PolarizerMonitor(every_n=1)
    lay = parse_layout()
    mon.feed(f.mosaic, scene.camera, lay, 35.0)  # warm-up
    t = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        rep = mon.feed(f.mosaic, scene.camera, lay, 35.0)
        t.append(time.perf_counter() - t0)
    return {
        'camera': [scene.camera.width_px, scene.camera.height_px],
        'check': timing_stats(t),
        'verdict': rep['verdict'],
        'margin': rep['margin'],
    }
