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
End-to-end latency of the heading_estimator node through rclpy.

Run as a child process by :mod:`bench.pipeline`, with loopback-only discovery, a domain id of its
own and the project's shared-memory Fast DDS profile for 10 MB images.

One process holds three nodes on one executor: a probe that publishes a rendered 12-bit mosaic
(``camera/image_raw``, mono16, system-default QoS as a driver would), the ``heading_estimator``
node (``least_squares``, superpixel demosaic, site and time from parameters) and a probe subscriber
on ``compass/<method>/status``. One frame is in flight at a time; latency = status received - image
published (wall clock), so it includes serialisation, DDS transport, decoding, demosaic, estimation
and publishing. Prints one JSON object. Usage: ``python -m bench.ros_latency '{"frames": 10,
"method": "least_squares"}'``.
"""

from __future__ import annotations

import json
import sys
import time


def main(argv) -> int:
    cfg = json.loads(argv[1]) if len(argv) > 1 else {}
    frames = int(cfg.get('frames', 10))
    method = str(cfg.get('method', 'least_squares'))
    tiny = bool(cfg.get('tiny', False))
    from polarization_compass.nodes.heading_estimator import HeadingEstimatorNode
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    cam, time_utc, mosaics = _render_mosaics(frames, tiny)
    rclpy.init(args=[])
    out = {
        'status': 'ok',
        'method': method,
        'frames': frames,
        'image_px': [cam.width_px, cam.height_px],
    }
    try:
        est = HeadingEstimatorNode(
            parameter_overrides=[
                Parameter('method', value=method),
                Parameter('camera_info_source', value='parameters'),
                Parameter('time_source', value='parameter'),
                Parameter('time_utc', value=time_utc),
                Parameter('prior_source', value='none'),
                Parameter('publish_ambiguous', value=True),
            ]
        )
        probe, pub, got = _probe_node(method, mosaics[0])
        ex = SingleThreadedExecutor()
        ex.add_node(est)
        ex.add_node(probe)
        if not _wait_for_subscriber(ex, pub):
            out['status'] = 'failed: the estimator never subscribed (discovery)'
            return _print(out)
        lat, est_ms, lost = _measure(ex, pub, got, mosaics, frames)
        out.update(_latency_stats(lat, est_ms, lost, got))
        est.destroy_node()
        probe.destroy_node()
    except Exception as exc:  # noqa: BLE001 - reported to the parent as JSON
        out['status'] = f'failed: {type(exc).__name__}: {exc}'
    finally:
        rclpy.try_shutdown()
    return _print(out)


def _render_mosaics(frames: int, tiny: bool):
    """Render up to four 12-bit mosaics (bearings 37 deg apart) and return the camera and time."""
    from polarization_compass.camera import CameraModel
    from polarization_compass.conventions import CameraAttitude
    from polarization_compass.render import Renderer
    from polarization_compass.scene_load import default_scene

    from .simulator import ALL_EFFECTS, sensor_config

    cam = CameraModel(width_px=192, height_px=160) if tiny else CameraModel()
    scene = default_scene().replace(camera=cam, sensor=sensor_config(ALL_EFFECTS, 'superpixel'))
    renderer = Renderer(scene)
    time_utc = '2019-11-15T06:00:00Z'
    sun = renderer.sun_at(time_utc)
    mosaics = [
        renderer.render(
            attitude=CameraAttitude(37.0 * k % 360.0, 0.0, 0.0), sun=sun, seed=k
        ).mosaic
        for k in range(min(frames, 4))
    ]
    return cam, time_utc, mosaics


def _probe_node(method: str, mosaic):
    """Create the probe node: the image publisher and a status subscriber recording arrivals."""
    from polarization_compass.nodes.msgs import image_msg
    from polarization_compass.specs import topics
    import rclpy
    from rclpy.qos import qos_profile_system_default, QoSProfile
    from std_msgs.msg import String

    probe = rclpy.create_node('bench_probe')
    pub = probe.create_publisher(
        type(image_msg(mosaic, 0, 'camera_link')), topics.IMAGE, qos_profile_system_default
    )
    got = []
    probe.create_subscription(
        String,
        topics.method_topics(method)['status'],
        lambda m: got.append((time.perf_counter(), json.loads(m.data))),
        QoSProfile(depth=50),
    )
    return probe, pub, got


def _wait_for_subscriber(ex, pub) -> bool:
    """Spin until the estimator subscribes to the image topic (discovery), at most 20 s."""
    t_end = time.perf_counter() + 20.0
    while pub.get_subscription_count() < 1 and time.perf_counter() < t_end:
        ex.spin_once(timeout_sec=0.05)
    return not pub.get_subscription_count() < 1


def _measure(ex, pub, got: list, mosaics: list, frames: int):
    """Publish ``frames`` + 1 images one at a time and time each until its status arrives."""
    from polarization_compass.nodes.msgs import image_msg

    lat, est_ms, lost = [], [], 0
    for k in range(frames + 1):
        msg = image_msg(mosaics[k % len(mosaics)], 1_000_000_000 * (k + 1), 'camera_link')
        n0 = len(got)
        t0 = time.perf_counter()
        pub.publish(msg)
        t_end = t0 + 10.0
        while len(got) == n0 and time.perf_counter() < t_end:
            ex.spin_once(timeout_sec=0.01)
        if len(got) == n0:
            lost += 1
            continue
        if k == 0:
            continue  # first frame: caches
        lat.append(got[-1][0] - t0)
        if 'estimate_ms' in got[-1][1]:
            est_ms.append(got[-1][1]['estimate_ms'])
    return lat, est_ms, lost


def _latency_stats(lat: list, est_ms: list, lost: int, got: list) -> dict:
    """Return the latency statistics [ms], the frames lost and the last status received."""
    import numpy as np

    s = np.asarray(lat) * 1e3
    return {
        'n': int(s.size),
        'lost': lost,
        'median_ms': float(np.median(s)) if s.size else None,
        'p95_ms': float(np.percentile(s, 95)) if s.size else None,
        'node_estimate_median_ms': float(np.median(est_ms)) if est_ms else None,
        'last_status': got[-1][1].get('status') if got else None,
    }


def _print(out) -> int:
    print(json.dumps(out))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))
