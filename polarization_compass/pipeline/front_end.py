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
Mosaic -> observation -> heading: the steps every road takes, and the nodes' front end.

Two steps, each written once: :func:`mosaic_observation` demosaics, from a raw mosaic read as a
:class:`MosaicReading` says, the pixels one method reads; :func:`estimate_checked` runs the method
on an observation and, when asked, checks the result against the whole sky
(:func:`polarization_compass.skyfit_assess.assess_result`). :class:`HeadingFrontEnd` (the nodes
and the replay, one method on live mosaics) and :mod:`polarization_compass.headings`
(``estimate``, the bench and the tests, on files) both call them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import PipelineError
from .sampling import whole_sky_sample
from ..camera import CameraModel
from ..demosaic import IFOV_K_DEFAULT
from ..mosaic import IMX250MZR_LAYOUT, IMX250MZR_POL45

__all__ = [
    'HeadingFrontEnd',
    'MosaicReading',
    'estimate_checked',
    'mosaic_observation',
    'warm_up',
]


# ------------------------------------------------------------------------------------------------
# The steps: a mosaic's observation, a checked estimate
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MosaicReading:
    """
    How a raw mosaic is read: its polarizer layout, the demosaic, and where it sits on the sensor.

    Parameters
    ----------
    layout : str or sequence
        The sensor's 2 x 2 polarizer angles [deg]
        (:func:`~polarization_compass.demosaic.parse_layout`).
    pol45_toward : str
        Image direction of the 45 deg polarizer.
    demosaic : {"superpixel", "bilinear"}, default "superpixel"
        Demosaicing.
    origin_px : tuple of int, default (1, 1)
        1-based sensor (x, y) of the mosaic's top-left sample (a full-sensor mosaic: (1, 1)).
    saturation_level : float, optional
        Samples at or above this are saturated; None: the dtype's maximum.
    ifov_k : float, default IFOV_K_DEFAULT
        IFOV check threshold [noise sigmas] (0 = off).
    intensity : bool, default False
        Also compute S0 as the observation's intensity.

    """

    layout: object
    pol45_toward: str
    demosaic: str = 'superpixel'
    origin_px: tuple = (1, 1)
    saturation_level: float | None = None
    ifov_k: float = IFOV_K_DEFAULT
    intensity: bool = False


def mosaic_observation(
    mosaic,
    camera: CameraModel,
    sun_azimuth_deg: float,
    sun_altitude_deg: float,
    reading: MosaicReading,
    selection,
    pitch_deg=None,
    roll_deg=None,
    prior_bearing_deg=None,
):
    """
    Demosaic, from a raw mosaic, the observation of the pixels one method reads.

    The one mosaic -> observation step of the live front end and of frame files:
    :func:`polarization_compass.estimators.mosaic_input.observation_from_mosaic` on the method's
    ``pixels_needed`` (strided superpixels, a region, or the zenith window and its whole-sky side
    grid, demosaiced sparsely).

    Parameters
    ----------
    mosaic : numpy.ndarray
        Raw DoFP image (uint8, uint16 or float), 2-D.
    camera : CameraModel
        The camera whose sensor the mosaic is (part of).
    sun_azimuth_deg : float
        Sun azimuth [deg], clockwise from North.
    sun_altitude_deg : float
        Sun altitude [deg].
    reading : MosaicReading
        The layout, demosaic, origin, saturation, IFOV check and intensity.
    selection : PixelSelection
        The pixels the method reads (its estimator's ``pixels_needed(camera)``).
    pitch_deg, roll_deg : float, optional
        Known camera pitch and roll [deg] (eq 21).
    prior_bearing_deg : float, optional
        Prior bearing of camera +y [deg, clockwise from North].

    Returns
    -------
    Observation
        AoP [rad, eq 28], DoP, rays and the sun, tilt and prior.

    Raises
    ------
    MosaicInputError
        The mosaic cannot be demosaiced as the reading says.

    """
    from ..estimators.mosaic_input import observation_from_mosaic

    return observation_from_mosaic(
        mosaic,
        camera,
        sun_azimuth_deg,
        sun_altitude_deg,
        origin_px=reading.origin_px,
        method=reading.demosaic,
        layout=reading.layout,
        pol45_toward=reading.pol45_toward,
        saturation_level=reading.saturation_level,
        selection=selection,
        with_intensity=reading.intensity,
        pitch_deg=pitch_deg,
        roll_deg=roll_deg,
        prior_bearing_deg=prior_bearing_deg,
        ifov_k=reading.ifov_k,
    )


def estimate_checked(
    estimator, obs, sky_check: bool = False, sample=None, principal_point_sigma_px=None
):
    """
    Estimate one method's heading and, with ``sky_check``, check it against the whole sky.

    The check is :func:`polarization_compass.skyfit_assess.assess_result` (misfit sigma, 180 deg
    side, ``poor_fit``) at the observation's own sun altitude, tilt and prior. Then the principal
    point's uncertainty, as the camera tilt it is equivalent to, grows the sigma
    (:func:`.optical_centre.with_principal_point_sigma`): the sky cannot see a principal point
    off across the sun's image direction, so only its stated uncertainty can cover it.

    Parameters
    ----------
    estimator : Estimator
        The method's estimator.
    obs : Observation
        What it reads.
    sky_check : bool, default False
        Check the result against ``sample``.
    sample : SkySample, optional
        The whole-sky sample of the same frame (:func:`.sampling.whole_sky_sample` of a mosaic,
        :func:`.sampling.observation_sky_sample` of a whole image); None when too little sky is
        usable.
    principal_point_sigma_px : float, optional
        The principal point's 1-sigma [px] the calibration states; None or negative: a
        calibration's typical one (:data:`.optical_centre.DEFAULT_PRINCIPAL_POINT_SIGMA_F` of the
        focal length); 0: exact (a rendered frame's own camera).

    Returns
    -------
    HeadingResult
        The method's result, checked when asked, its sigma grown by the principal point's share.

    """
    from .optical_centre import with_principal_point_sigma

    res = estimator.estimate(obs)
    if sky_check:
        from ..skyfit_assess import assess_result

        res = assess_result(
            res,
            sample,
            obs.sun_altitude_deg,
            obs.pitch_deg,
            obs.roll_deg,
            obs.prior_bearing_deg,
        )
    return with_principal_point_sigma(
        res,
        obs.camera,
        principal_point_sigma_px,
        obs.sun_altitude_deg,
        obs.pitch_deg,
        obs.roll_deg,
    )


# ------------------------------------------------------------------------------------------------
# The nodes' front end: one method on live mosaics
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
        Check each result against the whole sky
        (:func:`~polarization_compass.skyfit_assess.assess_result` on :func:`whole_sky_sample`:
        misfit sigma, 180 deg side, ``poor_fit``; ~15-30 ms per frame), as ``estimate`` does on
        real images.
    principal_point_sigma_px : float, optional
        The principal point's 1-sigma [px] the calibration states (the node's parameter of that
        name); None or negative: a calibration's typical one
        (:func:`~.optical_centre.principal_point_sigma_px`). Grows every heading's sigma
        (:func:`estimate_checked`).

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
        principal_point_sigma_px: float | None = None,
    ):
        from ..estimators import make_estimator
        from ..mosaic import parse_layout

        self.principal_point_sigma_px = principal_point_sigma_px
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
        :func:`mosaic_observation` (the step frame files take too) with this front end's layout,
        demosaic and intensity.

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
        from ..estimators.mosaic_input import MosaicInputError

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
        reading = MosaicReading(
            layout.angles_deg, layout.pol45_toward, demosaic, intensity=intensity
        )
        try:
            return mosaic_observation(
                m,
                camera,
                sun_azimuth_deg,
                sun_altitude_deg,
                reading,
                est.pixels_needed(camera),
                pitch_deg,
                roll_deg,
                prior_bearing_deg,
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

        :meth:`observation`, then :func:`estimate_checked` (with :attr:`sky_check`, on the
        mosaic's :func:`~polarization_compass.pipeline.sampling.whole_sky_sample`).

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
        est, layout, sky_check = self.estimator, self.layout, self.sky_check
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
        sample = whole_sky_sample(mosaic, camera, layout) if sky_check else None
        return estimate_checked(est, obs, sky_check, sample, self.principal_point_sigma_px)


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
