"""Node pipeline latency: what the heading-estimator node does per image, stage by stage (ROS-free
timing of the same functions the node calls), and end to end through rclpy on loopback when the
node exists.

Stages: decode the ``sensor_msgs/Image`` mosaic (``nodes.msgs.decode_image``), demosaic to AoP/DoP,
estimate the heading (``least_squares`` on superpixels, the node's default), build the
robot_localization ``Imu`` message. Single core.
"""
from __future__ import annotations

import time

import numpy as np

from polarization_compass.camera import CameraModel
from polarization_compass.conventions import CameraAttitude
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene

from .common import Unavailable, optional_import, single_core, timing_stats

METHOD = "least_squares"


def run(cfg) -> dict:
    msgs = optional_import("polarization_compass.nodes.msgs")
    dm = optional_import("polarization_compass.demosaic")
    est_mod = optional_import("polarization_compass.estimators")
    from polarization_compass.estimators.base import Observation
    from . import simulator
    cam = CameraModel(width_px=192, height_px=160) if cfg.tiny else CameraModel()
    scene = Scene(camera=cam, sky={"model": "rayleigh", "dop_max": 0.7},
                  sensor=simulator.sensor_config(simulator.ALL_EFFECTS, "superpixel"))
    renderer = Renderer(scene)
    frames = int(cfg.pipeline_frames) if not cfg.tiny else 3
    fn = dm.polarization_from_mosaic
    est = est_mod.make_estimator(METHOD)
    stage_t = {k: [] for k in ("decode_image", "demosaic", "estimate", "imu_message", "total")}
    rng = np.random.default_rng(5)
    errors = []
    for k in range(frames + 1):
        sun = SunDirection(float(rng.uniform(0, 360)), float(rng.uniform(15, 60)))
        att = CameraAttitude(float(rng.uniform(0, 360)), 0.0, 0.0)
        frame = renderer.render(attitude=att, sun=sun, seed=k)
        msg = msgs.image_msg(frame.mosaic, 1_000_000_000 + k, "camera_link")
        with single_core():
            t0 = time.perf_counter()
            mosaic = msgs.decode_image(msg)
            t1 = time.perf_counter()
            demo = fn(mosaic, method="superpixel")
            t2 = time.perf_counter()
            obs = _observation(demo, frame, cam, Observation)
            res = est.estimate(obs)
            t3 = time.perf_counter()
            if res.ok:
                msgs.heading_imu(1_000_000_000 + k, "base_link", np.radians(res.yaw_enu_deg),
                                 np.radians(res.sigma_deg) ** 2 if res.sigma_deg else 1e-4, 1e3)
            t4 = time.perf_counter()
        if k == 0:
            continue                          # warm-up
        for name, dt in (("decode_image", t1 - t0), ("demosaic", t2 - t1), ("estimate", t3 - t2),
                         ("imu_message", t4 - t3), ("total", t4 - t0)):
            stage_t[name].append(dt)
        if res.ok:
            from polarization_compass.conventions import fold_axial_deg
            errors.append(float(fold_axial_deg(res.psi_deg - frame.psi_deg)))
    out = {"method": METHOD, "frames": frames, "camera": {"width_px": cam.width_px, "height_px": cam.height_px},
           "stages": {k: timing_stats(v) for k, v in stage_t.items()},
           "heading_error_rms_deg": float(np.sqrt(np.mean(np.square(errors)))) if errors else None}
    out["end_to_end"] = _end_to_end(cfg)
    return out


def _observation(demo, frame, cam, Observation):
    """An Observation from the demosaic output (a Frame-like object or a dict/tuple with aop/dop/valid)."""
    if hasattr(demo, "aop_rad"):
        aop, dop, valid = demo.aop_rad, demo.dop, getattr(demo, "valid", None)
    elif isinstance(demo, dict):
        aop, dop, valid = demo["aop_rad"], demo["dop"], demo.get("valid")
    else:
        aop, dop = demo[0], demo[1]
        valid = demo[2] if len(demo) > 2 else None
    if np.shape(aop) == frame.aop_rad.shape:
        v = frame.valid if valid is None else (np.asarray(valid) & frame.valid)
        return Observation(aop, dop, v, frame.rays_cam, frame.x_px, frame.y_px, cam, frame.sun.azimuth_deg,
                           frame.sun.altitude_deg)
    raise Unavailable(f"demosaic output shape {np.shape(aop)} differs from the frame's {frame.aop_rad.shape}; "
                      "pipeline bench needs the superpixel geometry")


def _end_to_end(cfg) -> dict:
    try:
        optional_import("polarization_compass.nodes.heading_estimator")
    except Unavailable as exc:
        return {"status": f"unavailable: {exc}"}
    return {"status": "not implemented yet"}
