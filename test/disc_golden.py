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
Frames and stored answers of sm_asm and symmetry before their speed-up (a golden test's data).

``python test/disc_golden.py`` (from the repository root, with the package on PYTHONPATH) writes
``test/data/disc_golden.npz``: psi, sigma, status and reason of sm_asm and symmetry, with and
without sigma, on every case of :func:`cases`. It was run on main at 9edd6dd (the DoP-symmetric
pair weights, before their passes were made faster), with BLAS on one thread (``source
/work/wt/env.sh``; the Makefile sets the same); the case of a complete disc as a pixel list was
added later, stored from the estimators of 9edd6dd on main at e4f3955 (the other answers came out
bit-identical); ``test_disc_golden.py`` checks
that the faster code gives the same answers (an optimisation must not change behaviour). The
frames are rendered when the test runs, and they are bit-reproducible only with BLAS on one thread
(a threaded BLAS moved sigma by up to 1.6e-9 deg); if the renderer changes them, the test fails
without an estimator change: then regenerate from the estimators at 9edd6dd over current main
(``git archive 9edd6dd polarization_compass/estimators`` unpacked over an archive of main, on
PYTHONPATH).

Cases: ideal (level and tilted), Gaussian AoP noise, broken clouds 30 / 70 % and overcast (with
and without noise), a half-occluded disc, the same as a pixel list, a complete cloudy disc as a
pixel list, a region that cuts the disc, a noisy IMX250MZR mosaic through the superpixel front end
(tilted) and the three real frames of ``test/data/real-sky``.
"""

from __future__ import annotations

import math
from pathlib import Path
import sys

import numpy as np

OUT = Path(__file__).parent / 'data' / 'disc_golden.npz'
METHODS = ('sm_asm', 'symmetry')
#: (method knobs) per case family: the default stride and coarser ones
STRIDES = (8, 16, 32)


def _render_obs(est, scene, bearing, pitch=0.0, roll=0.0, sun=(160.0, 35.0)):
    from polarization_compass.conventions import CameraAttitude
    from polarization_compass.estimators import Observation
    from polarization_compass.render import Renderer, SunDirection

    f = Renderer(scene, pixels=est.pixels_needed(scene.camera)).render(
        attitude=CameraAttitude(bearing, pitch, roll), sun=SunDirection(*sun)
    )
    return f, Observation.from_frame(f, camera=scene.camera)


def _scene(coverage=None, thickness=3.0, seed=0):
    from polarization_compass.scene_load import default_scene

    atm = {}
    if coverage is not None:
        atm = {'clouds': {'coverage': coverage, 'optical_thickness': thickness}}
    return (
        default_scene()
        .replace(
            sky={'model': 'rayleigh', 'dop_max': 0.7},
            radiance={'model': 'cie_clear'},
            atmosphere=atm,
        )
        .replace(seed=seed)
    )


def _noisy(obs, seed, deg=2.0):
    rng = np.random.default_rng(seed)
    p = np.maximum(np.asarray(obs.dop, float), 0.05)
    noise = rng.normal(0.0, math.radians(deg), p.shape) * 0.3 / p
    obs.aop_rad = (np.asarray(obs.aop_rad) + noise).astype(np.asarray(obs.aop_rad).dtype)
    return obs


def _half_plane(obs, angle_rad):
    cam = obs.camera
    u = np.asarray(obs.x_px, dtype=float) - cam.cx_px
    v = np.asarray(obs.y_px, dtype=float) - cam.cy_px
    keep = (u * math.cos(angle_rad) + v * math.sin(angle_rad)) >= 0.0
    obs.valid = np.asarray(obs.valid) & keep
    return obs


def _as_list(obs):
    from polarization_compass.estimators import Observation

    def flat(a):
        return np.asarray(a).reshape(-1)[::-1]  # a pixel list (reversed: not in grid order)

    return Observation(
        flat(obs.aop_rad),
        flat(obs.dop),
        flat(obs.valid),
        np.asarray(obs.rays_cam).reshape(3, -1)[:, ::-1],
        flat(np.asarray(obs.x_px, float)),
        flat(np.asarray(obs.y_px, float)),
        obs.camera,
        obs.sun_azimuth_deg,
        obs.sun_altitude_deg,
    )


def _mosaic_obs(stride):
    from polarization_compass.conventions import CameraAttitude
    from polarization_compass.estimators import make_estimator
    from polarization_compass.estimators.mosaic_input import observation_from_mosaic
    from polarization_compass.render import Renderer, SunDirection
    from polarization_compass.scene_load import load_scene

    cfg = Path(__file__).resolve().parents[1] / 'config' / 'scenes' / 'imx250mzr_noisy.yaml'
    scene = load_scene(str(cfg))
    frame = Renderer(scene).render(
        attitude=CameraAttitude(40.0, 5.0, -3.0), sun=SunDirection(0.0, 35.0), seed=1
    )
    sel = make_estimator('sm_asm', stride=stride).pixels_needed(scene.camera)
    return observation_from_mosaic(
        frame.mosaic,
        scene.camera,
        0.0,
        35.0,
        method='superpixel',
        selection=sel,
        saturation_level=4095,
        pitch_deg=5.0,
        roll_deg=-3.0,
    )


def _real_obs(stem):
    sys.path.insert(0, str(Path(__file__).parent))
    import tempfile

    from polarization_compass.camera_file import load_camera_yaml
    from polarization_compass.pipeline.real_image import real_observation
    from polarization_compass.real_input import PolarizationInput
    import real_sky as R

    i, q, u = R.read_quadrants(stem)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / 'cam.yaml'
        p.write_text(R.camera_yaml_text('+x-y'))
        cam_file = load_camera_yaml(str(p))
    inp = PolarizationInput(kind='stokes', path=f'{stem}.npz', stokes=(i, q, u))
    obs, _ = real_observation(inp, cam_file, 0.0, R.sun_altitude_deg(stem))
    return obs


def cases():
    """
    Yield (case name, method knobs, observation) for every case (deterministic).

    The observation is rendered at the pixels the knobs' estimator reads (one per knob set).
    """
    from polarization_compass.estimators import make_estimator

    for stride in STRIDES:
        est = make_estimator('sm_asm', stride=stride)
        kn = {'stride': stride}
        sc = _scene()
        yield f'ideal_s{stride}', kn, _render_obs(est, sc, 30.0)[1]
        yield f'tilted_s{stride}', kn, _render_obs(est, sc, 110.0, 8.0, -4.0)[1]
        yield f'noisy_s{stride}', kn, _noisy(_render_obs(est, sc, 250.0)[1], stride)
        clouds = ((0.3, 3.0, 'clouds30'), (0.7, 3.0, 'clouds70'), (1.0, 2.0, 'overcast'))
        for cov, th, tag in clouds:
            for seed in range(2):
                scc = _scene(cov, th, seed)
                obs = _render_obs(est, scc, 30.0 + 70.0 * seed, sun=(160.0, 20.0 + 25.0 * seed))[1]
                yield f'{tag}_seed{seed}_s{stride}', kn, obs
                obs = _render_obs(est, scc, 200.0 + 50.0 * seed)[1]
                yield f'{tag}_noisy_seed{seed}_s{stride}', kn, _noisy(obs, 100 + seed)
        for k, ang in enumerate((0.4, 1.9)):
            obs = _half_plane(_render_obs(est, sc, 60.0 + 90.0 * k)[1], ang)
            yield f'occluded{k}_s{stride}', kn, obs
            if stride == 16:
                yield f'occluded{k}_list_s{stride}', kn, _as_list(obs)
        if stride == 16:  # a complete disc as a pixel list: its coarse blocks take a second pass
            obs = _render_obs(est, _scene(0.3, 3.0, 1), 320.0)[1]
            yield f'clouds30_list_s{stride}', kn, _as_list(_noisy(obs, 11))
        obs = _half_plane(_render_obs(est, _scene(0.3, 3.0, 2), 75.0)[1], 2.5)
        yield f'occluded_cloudy_s{stride}', kn, _noisy(obs, 7)
        cam = sc.camera
        region = (int(cam.cx_px) - 900, int(cam.cy_px) - 700, 1500, 1400)
        est_r = make_estimator('sm_asm', stride=stride, region=region)
        yield f'region_s{stride}', dict(kn, region=region), _render_obs(est_r, sc, 140.0)[1]
    for stride in (8, 16):
        yield f'mosaic_s{stride}', {'stride': stride}, _mosaic_obs(stride)
    for stem in ('sunny', 'cloudy', 'image0'):
        obs = _real_obs(stem)
        for stride in (8, 16):
            yield f'real_{stem}_s{stride}', {'stride': stride}, obs


def answers(res) -> tuple:
    """(psi deg or NaN, sigma deg or NaN, status, reason) of a result."""
    psi = math.nan if res.psi_deg is None else float(res.psi_deg)
    sig = math.nan if res.sigma_deg is None else float(res.sigma_deg)
    return psi, sig, res.status.value, res.reason or ''


def run_all():
    """Return {key: answers} for every case x method x sigma (keys 'case|method|sigma')."""
    from polarization_compass.estimators import make_estimator

    out = {}
    for name, kn, obs in cases():
        for m in METHODS:
            est = make_estimator(m, **kn)
            for sig in (True, False):
                out[f'{name}|{m}|{int(sig)}'] = answers(est.estimate(obs, sigma=sig))
    return out


def main() -> int:
    res = run_all()
    keys = sorted(res)
    np.savez_compressed(
        OUT,
        keys=np.array(keys),
        psi=np.array([res[k][0] for k in keys]),
        sigma=np.array([res[k][1] for k in keys]),
        status=np.array([res[k][2] for k in keys]),
        reason=np.array([res[k][3] for k in keys]),
    )
    print(f'{OUT}: {len(keys)} answers')
    return 0


if __name__ == '__main__':
    sys.exit(main())
