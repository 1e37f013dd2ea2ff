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
Node pipeline latency, stage by stage and end to end.

Node pipeline latency: what the heading-estimator node does per image, stage by stage (ROS-free
timing of the same functions the node calls), and end to end through rclpy on loopback when the
node exists.

Stages (the node's own ROS-free front end, :class:`polarization_compass.pipeline.HeadingFrontEnd`):
decode the ``sensor_msgs/Image`` mosaic (``nodes.msgs.decode_image``), demosaic to an observation,
estimate the heading (``least_squares`` on superpixels, the node's default), build the
robot_localization ``Imu`` message. Single core. End to end: :mod:`bench.ros_latency`.
"""

from __future__ import annotations

import time

import numpy as np
from polarization_compass.camera import CameraModel
from polarization_compass.conventions import CameraAttitude
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene

from .common import optional_import, single_core, timing_stats, Unavailable

METHOD = 'least_squares'


def run(cfg) -> dict:
    msgs = optional_import('polarization_compass.nodes.msgs')
    optional_import('polarization_compass.pipeline')
    from . import simulator

    cam = CameraModel(width_px=192, height_px=160) if cfg.tiny else CameraModel()
    scene = Scene(
        camera=cam,
        sky={'model': 'rayleigh', 'dop_max': 0.7},
        sensor=simulator.sensor_config(simulator.ALL_EFFECTS, 'superpixel'),
    )
    renderer = Renderer(scene)
    frames = int(cfg.pipeline_frames) if not cfg.tiny else 3
    from polarization_compass.pipeline import HeadingFrontEnd

    front = HeadingFrontEnd(METHOD, demosaic='superpixel')
    stage_t = {
        k: []
        for k in ('decode_image', 'demosaic_to_observation', 'estimate', 'imu_message', 'total')
    }
    rng = np.random.default_rng(5)
    errors = []
    for k in range(frames + 1):
        sun = SunDirection(float(rng.uniform(0, 360)), float(rng.uniform(15, 60)))
        att = CameraAttitude(float(rng.uniform(0, 360)), 0.0, 0.0)
        frame = renderer.render(attitude=att, sun=sun, seed=k)
        msg = msgs.image_msg(frame.mosaic, 1_000_000_000 + k, 'camera_link')
        with single_core():
            t0 = time.perf_counter()
            mosaic = msgs.decode_image(msg)
            t1 = time.perf_counter()
            obs = front.observation(mosaic, cam, sun.azimuth_deg, sun.altitude_deg)
            t2 = time.perf_counter()
            res = front.estimator.estimate(obs)
            t3 = time.perf_counter()
            if res.ok:
                msgs.heading_imu(
                    1_000_000_000 + k,
                    'base_link',
                    np.radians(res.yaw_enu_deg),
                    np.radians(max(res.sigma_deg or 0.0, 0.01)) ** 2,
                    1e3,
                )
            t4 = time.perf_counter()
        if k == 0:
            continue  # warm-up
        for name, dt in (
            ('decode_image', t1 - t0),
            ('demosaic_to_observation', t2 - t1),
            ('estimate', t3 - t2),
            ('imu_message', t4 - t3),
            ('total', t4 - t0),
        ):
            stage_t[name].append(dt)
        if res.ok:
            from polarization_compass.conventions import fold_axial_deg

            errors.append(float(fold_axial_deg(res.psi_deg - frame.psi_deg)))
    out = {
        'method': METHOD,
        'frames': frames,
        'camera': {'width_px': cam.width_px, 'height_px': cam.height_px},
        'stages': {k: timing_stats(v) for k, v in stage_t.items()},
        'heading_error_rms_deg': float(np.sqrt(np.mean(np.square(errors)))) if errors else None,
    }
    # tiny (smoke-test) mode: starting rclpy and the node's warm-up costs ~10 s; not worth it there
    out['end_to_end'] = {'status': 'skipped in tiny mode'} if cfg.tiny else _end_to_end(cfg)
    return out


def _end_to_end(cfg) -> dict:
    """Run :mod:`bench.ros_latency` in a child process (loopback DDS, own domain id)."""
    import json
    import os
    from pathlib import Path
    import random
    import subprocess
    import sys

    try:
        optional_import('rclpy')
        optional_import('polarization_compass.nodes.heading_estimator')
    except Unavailable as exc:
        return {'status': f'unavailable: {exc}'}
    repo = Path(__file__).resolve().parent.parent
    env = dict(
        os.environ,
        ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
        ROS_DOMAIN_ID=str(random.Random(os.getpid()).randint(150, 220)),
        PYTHONUNBUFFERED='1',
        NUMBA_NUM_THREADS=os.environ.get('NUMBA_NUM_THREADS', '1'),
    )
    profile = repo / 'config' / 'fastdds_large_images.xml'
    if profile.is_file():
        env['FASTDDS_DEFAULT_PROFILES_FILE'] = str(profile)
    args = json.dumps(
        {'frames': 3 if cfg.tiny else int(cfg.pipeline_frames), 'method': METHOD, 'tiny': cfg.tiny}
    )
    try:
        p = subprocess.run(
            [sys.executable, '-m', 'bench.ros_latency', args],
            cwd=repo,
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
        )
    except subprocess.TimeoutExpired:
        return {'status': 'failed: timed out after 300 s'}
    lines = [ln for ln in p.stdout.strip().splitlines() if ln.startswith('{')]
    if p.returncode != 0 or not lines:
        return {'status': f'failed: exit {p.returncode}: {p.stderr.strip()[-300:]}'}
    res = json.loads(lines[-1])
    res['fastdds_profile'] = profile.name if profile.is_file() else None
    res['numba_threads'] = env['NUMBA_NUM_THREADS']
    return res
