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
What the ``sky_simulator`` node simulates, without ROS: its scene, each frame's mosaic, odometry.

:func:`simulation_scene` loads the scene (with a photodiode array of a given geometry when asked),
:func:`frame_mosaic` renders one frame and turns it into the raw mosaic its encoding sends, and
:class:`WheelOdometry` integrates a yaw rate into the dead-reckoned yaw of a wheel odometry. The
node (:mod:`polarization_compass.nodes.sky_simulator`) wraps them in messages.
"""

from __future__ import annotations

import numpy as np

from .errors import CompassError

__all__ = ['WheelOdometry', 'frame_mosaic', 'simulation_scene']


def simulation_scene(scene_file: str, array_geometry: str = ''):
    """
    Load the simulator's scene, with a photodiode array of ``array_geometry`` when given.

    Parameters
    ----------
    scene_file : str
        A scene YAML file or name (:func:`~polarization_compass.scene_load.load_scene`); empty for
        the default scene.
    array_geometry : str, default ""
        When set, the scene also simulates a photodiode-array compass of this geometry (its
        other ``photodiode_array`` settings kept).

    Returns
    -------
    Scene
        The scene.

    Raises
    ------
    CompassError
        The scene cannot be loaded or is invalid.

    """
    from .scene import SceneError
    from .scene_load import load_scene

    try:
        scene = load_scene(scene_file or None)
        if array_geometry:  # also simulate a photodiode-array compass with this geometry
            from .scene_load import scene_from_dict

            scene = scene_from_dict(
                {
                    **scene.to_dict(),
                    'photodiode_array': {
                        **(scene.photodiode_array or {}),
                        'geometry': array_geometry,
                    },
                }
            )
    except SceneError as exc:
        raise CompassError(str(exc)) from None
    return scene


def frame_mosaic(renderer, sensor_cfg, encoding: str, attitude, sun_az_alt_deg, rng):
    """
    Render one frame and simulate the sensor's raw mosaic of it.

    Parameters
    ----------
    renderer : Renderer
        The scene's renderer (its sensor effects left to ``sensor_cfg``).
    sensor_cfg : SensorConfig
        The sensor of the image encoding
        (:func:`~polarization_compass.sensor.sensor_config_for_encoding`).
    encoding : str
        The image encoding; ``32FC1`` gives float32 electrons.
    attitude : CameraAttitude
        The camera's attitude.
    sun_az_alt_deg : tuple of float
        The sun's azimuth and altitude [deg].
    rng : numpy.random.Generator
        The frame's noise stream.

    Returns
    -------
    mosaic : numpy.ndarray
        The raw mosaic (DN, or float32 electrons with ``32FC1``).
    array_intensities : numpy.ndarray or None
        The photodiode array's sample of the frame, None without an array.

    """
    from .render import SunDirection
    from .sensor import simulate_mosaic

    frame = renderer.render(attitude=attitude, sun=SunDirection(*sun_az_alt_deg))
    mosaic = simulate_mosaic(
        frame.aop_rad, frame.dop, frame.intensity, sensor_cfg, sensor_cfg.layout, rng
    )
    if encoding == '32FC1':
        mosaic = np.ascontiguousarray(mosaic, dtype=np.float32)
    return mosaic, frame.array_intensities


class WheelOdometry:
    """
    Dead reckoning of a wheel odometry's yaw: the integral of its yaw rate, from yaw 0.

    Attributes
    ----------
    yaw_rad : float
        The dead-reckoned yaw [rad] (REP-103, in the odometry's own ``odom`` frame).
    last_ns : int or None
        The stamp [ns] of the last rate integrated, None before the first.

    """

    def __init__(self):
        self.yaw_rad = 0.0
        self.last_ns = None

    def step(self, t_ns: int, yaw_rate_rad_s: float) -> float:
        """
        Integrate the yaw rate since the last stamp (rectangle rule) and return the yaw.

        Parameters
        ----------
        t_ns : int
            Stamp of this rate [ns].
        yaw_rate_rad_s : float
            The measured yaw rate [rad/s], held since the last stamp.

        Returns
        -------
        float
            The dead-reckoned yaw at ``t_ns`` [rad].

        """
        if self.last_ns is not None:
            self.yaw_rad += yaw_rate_rad_s * (t_ns - self.last_ns) * 1e-9
        self.last_ns = t_ns
        return self.yaw_rad
