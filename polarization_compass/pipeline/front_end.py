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

"""Mosaic -> observation -> heading: one method's front end, as the nodes and the replay run it."""

from __future__ import annotations

import numpy as np

from .errors import PipelineError
from .sampling import whole_sky_sample
from ..camera import CameraModel
from ..mosaic import IMX250MZR_LAYOUT, IMX250MZR_POL45

__all__ = ['HeadingFrontEnd', 'warm_up']


# ------------------------------------------------------------------------------------------------
# Mosaic -> observation -> heading
# ------------------------------------------------------------------------------------------------
class HeadingFrontEnd:
    """
    Turn a raw mosaic into a heading with one method and its knobs.

    A raw mosaic (uint8/uint16/float32) plus the camera, the sun and optionally the tilt and a
    prior bearing in, a :class:`~polarization_compass.estimators.HeadingResult` out.

    Parameters
    ----------
    method : str
        Name of the method (:mod:`~polarization_compass.estimators.registry`).
    knobs : dict, optional
        The method's knobs.
    layout : str or sequence, default IMX250MZR_LAYOUT
        The sensor's 2 x 2 polarizer pattern [deg] (:mod:`~polarization_compass.demosaic`).
    pol45_toward : str, default "+x-y"
        Image direction of the 45 deg polarizer (IMX250MZR as delivered: +x-y).
    demosaic : {"superpixel", "bilinear"}, default "superpixel"
        Demosaicing.
    intensity : bool, default False
        Also compute S0 and pass it as the observation's intensity (lets a method resolve the 180
        deg ambiguity from the sky's brightness gradient).
    sky_check : bool, default False
        Check each result against the whole sky (:func:`~polarization_compass.skyfit.assess_result`
        on :func:`whole_sky_sample`: misfit sigma, 180 deg side, ``poor_fit``; ~15-30 ms per
        frame), as ``estimate`` does on real images.

    Raises
    ------
    EstimatorError
        Unknown method or knob.

    """

    def __init__(
        self,
        method: str,
        knobs: dict | None = None,
        layout=IMX250MZR_LAYOUT,
        pol45_toward: str = IMX250MZR_POL45,
        demosaic: str = 'superpixel',
        intensity: bool = False,
        sky_check: bool = False,
    ):
        from ..estimators import make_estimator
        from ..mosaic import parse_layout

        self.method = method
        self.estimator = make_estimator(method, **(knobs or {}))
        self.layout = parse_layout(layout, pol45_toward)
        self.demosaic = demosaic
        self.intensity = bool(intensity)
        self.sky_check = bool(sky_check)

    def set_knobs(self, knobs: dict) -> None:
        """
        Replace the estimator's knobs; the old ones stay when the new ones are refused.

        Parameters
        ----------
        knobs : dict
            The method's knobs.

        Raises
        ------
        EstimatorError
            A knob is unknown or out of range (the message says which).

        """
        from ..estimators import make_estimator

        self.estimator = make_estimator(self.method, **knobs)

    def set_layout(self, layout, pol45_toward: str) -> None:
        """
        Replace the sensor's polarizer layout.

        Parameters
        ----------
        layout : str or sequence
            The 2 x 2 polarizer pattern [deg]
            (:func:`~polarization_compass.demosaic.parse_layout`).
        pol45_toward : str
            Image direction of the 45 deg polarizer.

        """
        from ..mosaic import parse_layout

        self.layout = parse_layout(layout, pol45_toward)

    def observation_key(self, camera: CameraModel) -> tuple:
        """
        Key this method's observation of a frame, so a replay demosaics once per distinct key.

        Equal keys give equal observations: the pixels are the estimator's ``pixels_needed`` (a
        disc for sm_asm/symmetry, a strided frame for least squares, a window and side grid for
        zenith), plus the demosaic, intensity and layout.

        Parameters
        ----------
        camera : CameraModel
            The camera the frames come from.

        Returns
        -------
        tuple
            A hashable key.

        """
        return (self.estimator.pixels_needed(camera), self.demosaic, self.intensity, self.layout)

    def observation(
        self,
        mosaic: np.ndarray,
        camera: CameraModel,
        sun_azimuth_deg: float,
        sun_altitude_deg: float,
        pitch_deg=None,
        roll_deg=None,
        prior_bearing_deg=None,
        estimator=None,
    ):
        """
        Build the estimator's observation of a full-sensor mosaic.

        Only the pixels the method reads (its ``pixels_needed``: strided superpixels, a region, or
        the zenith window and its whole-sky side grid, demosaiced sparsely) are demosaiced, by
        :func:`polarization_compass.estimators.mosaic_input.observation_from_mosaic`.

        Parameters
        ----------
        mosaic : numpy.ndarray
            Raw DoFP image, the camera's (height, width).
        camera : CameraModel
            The camera.
        sun_azimuth_deg : float
            Sun azimuth [deg], clockwise from North.
        sun_altitude_deg : float
            Sun altitude [deg].
        pitch_deg, roll_deg : float, optional
            Known camera pitch and roll [deg] (eq 21).
        prior_bearing_deg : float, optional
            Prior bearing of camera +y [deg, clockwise from North].
        estimator : Estimator, optional
            The estimator whose pixels to read; this front end's by default.

        Returns
        -------
        Observation
            AoP [rad, eq 28], DoP, rays and the sun, tilt and prior.

        Raises
        ------
        PipelineError
            The mosaic does not match the camera or cannot be demosaiced.

        """
        from ..estimators.mosaic_input import MosaicInputError, observation_from_mosaic

        # one consistent configuration for the whole frame (a node may change knobs from another
        # thread)
        est, demosaic, layout, intensity = (
            estimator or self.estimator,
            self.demosaic,
            self.layout,
            self.intensity,
        )
        m = np.asarray(mosaic)
        if m.shape != camera.shape:
            raise PipelineError(
                f'mosaic is {m.shape[1]}x{m.shape[0]}, the camera is '
                f'{camera.width_px}x{camera.height_px}'
            )
        try:
            return observation_from_mosaic(
                m,
                camera,
                sun_azimuth_deg,
                sun_altitude_deg,
                method=demosaic,
                layout=layout.angles_deg,
                pol45_toward=layout.pol45_toward,
                selection=est.pixels_needed(camera),
                with_intensity=intensity,
                pitch_deg=pitch_deg,
                roll_deg=roll_deg,
                prior_bearing_deg=prior_bearing_deg,
            )
        except MosaicInputError as exc:
            raise PipelineError(str(exc)) from None

    def estimate(
        self,
        mosaic,
        camera,
        sun_azimuth_deg,
        sun_altitude_deg,
        pitch_deg=None,
        roll_deg=None,
        prior_bearing_deg=None,
    ):
        """
        Estimate the heading of one full-sensor mosaic.

        Parameters
        ----------
        mosaic : numpy.ndarray
            Raw DoFP image, the camera's (height, width).
        camera : CameraModel
            The camera.
        sun_azimuth_deg : float
            Sun azimuth [deg], clockwise from North.
        sun_altitude_deg : float
            Sun altitude [deg].
        pitch_deg, roll_deg : float, optional
            Known camera pitch and roll [deg] (eq 21).
        prior_bearing_deg : float, optional
            Prior bearing of camera +y [deg, clockwise from North].

        Returns
        -------
        HeadingResult
            psi, bearing and REP-103 yaw [deg], or a failure status with a reason.

        Raises
        ------
        PipelineError
            The mosaic does not match the camera or cannot be demosaiced.

        """
        est, layout = self.estimator, self.layout
        obs = self.observation(
            mosaic,
            camera,
            sun_azimuth_deg,
            sun_altitude_deg,
            pitch_deg,
            roll_deg,
            prior_bearing_deg,
            est,
        )
        res = est.estimate(obs)
        if self.sky_check:
            from ..skyfit_assess import assess_result

            sample = whole_sky_sample(mosaic, camera, layout)
            res = assess_result(
                res, sample, sun_altitude_deg, pitch_deg, roll_deg, prior_bearing_deg
            )
        return res


def warm_up(
    front: HeadingFrontEnd, encoding_dtype=np.uint16, camera: CameraModel | None = None
) -> float:
    """
    Run a front end once on a rendered, slightly tilted frame so its numba kernels are compiled.

    Compiled (or loaded from the cache) before the first real image. With ``camera`` (the node's
    expected intrinsics) the frame has that camera's size, so the per-camera caches (rays, pixel
    selections, mirror maps) are built now too rather than on the first image; without, a tiny
    camera (kernels only).

    Parameters
    ----------
    front : HeadingFrontEnd
        The front end to warm up.
    encoding_dtype : numpy dtype, default numpy.uint16
        Dtype of the mosaics it will get (uint8, uint16, else float32).
    camera : CameraModel, optional
        The expected camera.

    Returns
    -------
    float
        Seconds it took.

    """
    import time

    from ..conventions import CameraAttitude
    from ..render import Renderer, SunDirection
    from ..scene_load import default_scene
    from ..sensor import sensor_config_for_encoding, simulate_mosaic

    t0 = time.perf_counter()
    cam = camera or CameraModel('pinhole', 96, 80, 4.0, 3.45 * 2448 / 96, 3.45 * 2448 / 96)
    scene = default_scene().replace(camera=cam)
    frame = Renderer(scene).render(
        attitude=CameraAttitude(30.0, -3.0, 2.0), sun=SunDirection(180.0, 30.0)
    )
    encoding = {np.dtype(np.uint8): 'mono8', np.dtype(np.uint16): 'mono16'}.get(
        np.dtype(encoding_dtype), '32FC1'
    )
    cfg = sensor_config_for_encoding({}, encoding)
    mosaic = simulate_mosaic(
        frame.aop_rad, frame.dop, frame.intensity, cfg, cfg.layout, np.random.default_rng(0)
    )
    front.estimate(mosaic, cam, 180.0, 30.0, -3.0, 2.0, 30.0)
    return time.perf_counter() - t0
