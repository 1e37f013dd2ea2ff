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
Issue 25: what the heading node's debug image and marker cost.

One core. Per image, :meth:`HeadingNodeBase._publish_debug`: ``debug_no_subscriber`` -- the debug
image on (``debug_rate_hz`` 1000), marker off, nobody subscribed (the picture is neither rendered
nor sent: the goal is ~0); ``marker_only`` -- the two marker messages; ``both_off`` -- the floor.
When someone subscribes, one picture: :func:`polarization_compass.sky_view.view_from_mosaic` (256
cells) then :func:`polarization_compass.diagnostic_rgb.quick_rgb` (640 px, what the node sends),
on a simulated ``imx250mzr_noisy`` mosaic (full 2448 x 2048; 192 x 160 with ``--tiny``); and for
comparison matplotlib's figure of the same view (``figure_rgb`` 640 px, ``save_figure``: the
1300 x 850 PNG of ``estimate --plot``).
"""

from __future__ import annotations

from pathlib import Path
import tempfile
import time
from types import SimpleNamespace

from .common import optional_import, single_core, timing_stats

ROOT = Path(__file__).resolve().parent.parent


def run(cfg) -> dict:
    optional_import('rclpy')
    optional_import('visualization_msgs.msg')
    # tiny (the smoke test): one repeat (matplotlib's figure and PNG take ~2 s a repeat)
    calls = 2000 if cfg.mode == 'full' else 200
    with single_core():
        out = {'publish_per_image_us': _publish_costs(calls)}
        out.update(_render_costs(cfg, {'full': 5, 'quick': 2}.get(cfg.mode, 1)))
    out['notes'] = (
        'per image: _publish_debug with the debug image on and no subscriber (no render), the '
        'marker alone, both off; render: view_from_mosaic + quick_rgb, only while subscribed and '
        'at most debug_rate_hz (default 1 Hz); matplotlib rows for comparison'
    )
    return out


class _Params(dict):
    """Parameter values as a node's ParameterSet gives them."""

    @property
    def values(self):
        return self


def _probe(ctx, name, marker, rate_hz):
    from polarization_compass.nodes.heading_node import HeadingNodeBase
    from rclpy.node import Node

    class Probe(HeadingNodeBase):
        """A heading node's debug outputs, its picture counted."""

        def __init__(self):
            Node.__init__(self, name, context=ctx)
            self.params = _Params(
                {'publish_marker': marker, 'debug_rate_hz': rate_hz, 'frame_id': 'base_link'}
            )
            self.diag = SimpleNamespace(reject=lambda *a: None)
            self.renders = 0
            self._start_debug(self.params)

        def _debug_rgb(self, prepared, data, result, sun, inp):
            self.renders += 1
            return None

    return Probe()


def _publish_costs(calls: int) -> dict:
    from polarization_compass.estimators import HeadingResult, Status
    import rclpy
    from rclpy.context import Context

    res = HeadingResult(
        'least_squares',
        Status.OK,
        '',
        psi_deg=10.0,
        bearing_deg=60.0,
        yaw_enu_deg=30.0,
        sigma_deg=1.0,
        pixels=1,
        quality=1.0,
    )
    ctx = Context()
    rclpy.init(context=ctx)
    out = {}
    try:
        for key, marker, rate in (
            ('debug_no_subscriber', False, 1000.0),
            ('marker_only', True, 0.0),
            ('both_off', False, 0.0),
        ):
            node = _probe(ctx, f'bench_debug_{key}', marker, rate)
            node._publish_debug(0, res, None, None, (0.0, 40.0), None, None)  # warm-up
            t = []
            for k in range(calls):
                t0 = time.perf_counter()
                node._publish_debug(k, res, None, None, (0.0, 40.0), None, None)
                t.append(time.perf_counter() - t0)
            st = timing_stats(t)
            out[key] = {
                'median_us': st['median_ms'] * 1e3,
                'p95_us': st['p95_ms'] * 1e3,
                'n': st['n'],
                'renders': node.renders,
            }
            node.destroy_node()
    finally:
        rclpy.shutdown(context=ctx)
    return out


def _render_costs(cfg, repeats: int) -> dict:
    from polarization_compass.camera import CameraModel
    from polarization_compass.conventions import CameraAttitude
    from polarization_compass.diagnostic_figure import figure_rgb, save_figure
    from polarization_compass.diagnostic_rgb import quick_rgb
    from polarization_compass.estimators import HeadingResult, Status
    from polarization_compass.pipeline.sun import Sun
    from polarization_compass.render import Renderer, SunDirection
    from polarization_compass.scene_load import load_scene
    from polarization_compass.sky_view import view_from_mosaic

    scene = load_scene(str(ROOT / 'config' / 'scenes' / 'imx250mzr_noisy.yaml'))
    if cfg.tiny:
        scene = scene.replace(camera=CameraModel(width_px=192, height_px=160))
    f = Renderer(scene).render(
        attitude=CameraAttitude(40.0, 0.0, 0.0), sun=SunDirection(135.0, 35.0), seed=3
    )
    res = [
        HeadingResult(
            'least_squares',
            Status.OK,
            '',
            psi_deg=-95.0,
            bearing_deg=40.0,
            yaw_enu_deg=50.0,
            sigma_deg=0.1,
            pixels=1,
            quality=1.0,
        )
    ]

    def view():
        return view_from_mosaic(
            f.mosaic,
            scene.camera,
            Sun(135.0, 35.0, 'bench'),
            res,
            [[90, 45], [135, 0]],
            '+x-y',
            max_side_px=256,
            sampled=True,
        )

    v = view()  # warm-up (kernels)
    figure_rgb(v)
    quick_rgb(v)
    t_view, t_quick, t_rgb, t_png = [], [], [], []
    with tempfile.TemporaryDirectory() as d:
        for _ in range(repeats):
            t0 = time.perf_counter()
            v = view()
            t1 = time.perf_counter()
            quick_rgb(v, 640)
            t_quick.append(time.perf_counter() - t1)
            t1 = time.perf_counter()
            figure_rgb(v, 640)
            t2 = time.perf_counter()
            save_figure(v, Path(d) / 'f.png')
            t3 = time.perf_counter()
            t_view.append(t1 - t0)
            t_rgb.append(t2 - t1)
            t_png.append(t3 - t2)
    return {
        'camera': [scene.camera.width_px, scene.camera.height_px],
        'render_view': timing_stats(t_view),
        'render_quick_rgb_640': timing_stats(t_quick),
        'matplotlib_figure_rgb_640': timing_stats(t_rgb),
        'save_figure_png': timing_stats(t_png),
    }
