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
The shared estimator interface: observation, result and the facts of each method.

What goes in: :class:`Observation`; what comes out: :class:`HeadingResult`; the facts every method
declares: :class:`Estimator`. The methods are listed by :mod:`.registry`.

Angles follow :mod:`polarization_compass.conventions`. A result never carries NaN or inf: a value
that does not exist is ``None`` and ``status``/``reason`` say why.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from enum import Enum
import math

import numpy as np

from ..camera import CameraModel
from ..camera_pixels import PixelSelection
from ..conventions import psi_to_bearing_deg, wrap_180_deg_float, wrap_360_deg_float
from ..errors import CompassError

__all__ = ['Status', 'HeadingResult', 'Observation', 'Estimator', 'EstimatorError']


class EstimatorError(CompassError):
    """Unknown method or out-of-range knob."""


class Status(str, Enum):
    """
    Outcome of one heading estimate; every value but ``OK`` and ``AMBIGUOUS`` means no heading.

    The values are strings (JSON, topics, tables). ``AMBIGUOUS``: the solar meridian was found but
    its 180 deg ambiguity was not resolved; the others name why no heading exists (sun near the
    zenith or below the horizon, too few pixels or units, outside an error map's domain, bad input,
    degenerate data, insufficient sky coverage, a poor fit to the sky model).
    """

    OK = 'ok'
    AMBIGUOUS = 'ambiguous'  # solar meridian found, 180 deg ambiguity not resolved
    SUN_NEAR_ZENITH = 'sun_near_zenith'  # the meridian is undefined / ill-conditioned
    SUN_BELOW_HORIZON = 'sun_below_horizon'
    TOO_FEW_PIXELS = 'too_few_pixels'
    OUT_OF_DOMAIN = 'out_of_domain'  # e.g. tilt outside an error map
    BAD_INPUT = 'bad_input'
    DEGENERATE = 'degenerate'  # numerically degenerate data (e.g. all E-vectors parallel)
    INSUFFICIENT_COVERAGE = (
        'insufficient_coverage'  # too little of the sky usable for the method's geometry
    )
    TOO_FEW_UNITS = 'too_few_units'  # photodiode array: fewer usable units than the method needs
    POOR_FIT = 'poor_fit'  # the data do not fit the sky model well enough to trust a heading
    INCONSISTENT = 'inconsistent'  # methods on the same frame disagree beyond their sigmas
    PRIOR_DISAGREES = (
        'prior_disagrees'  # the heading contradicts an independent prior (IMU yaw) beyond sigma
    )


@dataclass(frozen=True)
class HeadingResult:
    """
    One heading estimate.

    ``psi_deg``: the paper's yaw (bearing of camera +y minus sun azimuth), (-180, 180].
    ``bearing_deg``: true-North bearing of the camera +y axis, [0, 360).
    ``yaw_enu_deg``: REP-103 yaw (90 - bearing), (-180, 180].
    ``sigma_deg``: calibrated 1-sigma uncertainty of the yaw (None when the caller asked for no
    uncertainty: ``estimate(obs, sigma=False)``).
    ``axial``: True when the value is only known modulo 180 deg (status AMBIGUOUS).
    ``quality``: [0, 1], method specific (1 = perfect fit).
    Fields that do not exist for a failed estimate are ``None``.
    """

    method: str
    status: Status
    reason: str = ''
    psi_deg: float | None = None
    bearing_deg: float | None = None
    yaw_enu_deg: float | None = None
    sigma_deg: float | None = None
    pixels: int = 0
    quality: float = 0.0
    axial: bool = False
    sun_altitude_deg: float | None = (
        None  # implied by the data (least squares), a consistency check
    )
    extras: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """Return whether the heading is usable (possibly axial)."""
        return self.status in (Status.OK, Status.AMBIGUOUS) and self.psi_deg is not None

    @staticmethod
    def failed(
        method: str, status: Status, reason: str, pixels: int = 0, **extras
    ) -> 'HeadingResult':
        """
        Build the result of an estimate that has no heading.

        Parameters
        ----------
        method : str
            Name of the method (:mod:`.registry`).
        status : Status
            Why there is no heading (not ``OK`` or ``AMBIGUOUS``).
        reason : str
            One human-readable line with the numbers that decided it.
        pixels : int, default 0
            Number of pixels (or units) the method used before it stopped.
        **extras
            Method-specific diagnostics, stored in ``extras``.

        Returns
        -------
        HeadingResult
            A result whose heading fields are None.

        """
        return HeadingResult(method, status, reason, pixels=int(pixels), extras=dict(extras))

    @staticmethod
    def from_psi(
        method: str,
        psi_deg: float,
        sun_azimuth_deg: float,
        sigma_deg: float,
        pixels: int,
        quality: float,
        axial: bool,
        reason: str = '',
        **kw,
    ) -> 'HeadingResult':
        """
        Build a result from the paper's yaw psi, filling the true bearing and REP-103 yaw.

        ``bearing = psi + A_sun`` (eq 26 with its sign erratum fixed) and ``yaw_enu = 90 -
        bearing``.

        Parameters
        ----------
        method : str
            Name of the method (:mod:`.registry`).
        psi_deg : float
            Yaw psi [deg]: bearing of camera +y minus the sun's azimuth (eq 21); wrapped to (-180,
            180].
        sun_azimuth_deg : float
            Sun azimuth [deg], clockwise from North.
        sigma_deg : float or None
            1-sigma uncertainty of the yaw [deg]; None when not computed (``estimate(obs,
            sigma=False)``).
        pixels : int
            Number of pixels (or units) used.
        quality : float
            Method-specific fit quality, clipped to [0, 1] (1 = perfect fit).
        axial : bool
            The heading is known only modulo 180 deg (status ``AMBIGUOUS`` instead of ``OK``).
        reason : str, default ""
            Optional note (e.g. how the 180 deg ambiguity was resolved).
        **kw
            Further :class:`HeadingResult` fields (``sun_altitude_deg``, ``extras``).

        Returns
        -------
        HeadingResult
            Status ``OK`` or ``AMBIGUOUS``, bearing [deg, 0..360), yaw_enu [deg, (-180, 180]].

        Raises
        ------
        FloatingPointError
            ``psi_deg``, ``sigma_deg`` or ``quality`` is NaN or inf: a bug in the method, never an
            input.

        References
        ----------
        .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), eqs 21 and 26.

        """
        psi_deg, sun_azimuth_deg, quality = float(psi_deg), float(sun_azimuth_deg), float(quality)
        for name, v in (('psi_deg', psi_deg), ('sigma_deg', sigma_deg), ('quality', quality)):
            if v is not None and not math.isfinite(v):
                raise FloatingPointError(f'{method}: non-finite {name} reached a result')
        if not math.isfinite(sun_azimuth_deg):
            bearing = float(psi_to_bearing_deg(psi_deg, sun_azimuth_deg))  # nan, as before
        else:
            bearing = wrap_360_deg_float(psi_deg + sun_azimuth_deg)
        return HeadingResult(
            method,
            Status.AMBIGUOUS if axial else Status.OK,
            reason,
            wrap_180_deg_float(psi_deg),
            bearing,
            wrap_180_deg_float(90.0 - bearing),
            None if sigma_deg is None else float(sigma_deg),
            int(pixels),
            min(max(quality, 0.0), 1.0),
            bool(axial),
            **kw,
        )

    def to_json_dict(self) -> dict:
        """
        Convert the result to a JSON-ready dict.

        Returns
        -------
        dict
            The dataclass fields by name, ``status`` as its string value.

        """
        d = asdict(self)
        d['status'] = self.status.value
        return d


@dataclass
class Observation:
    """
    What an estimator sees. Images may be 2-D (a grid) or 1-D (a pixel list); all share a shape.

    ``aop_rad`` eq 28 convention; ``rays_cam`` (3, N) float32 unit rays in the order of
    ``aop_rad.reshape(-1)``; ``x_px``/``y_px`` 1-based eq 20 coordinates. The sun (azimuth
    clockwise from North, geometric altitude) comes from the ephemeris; it turns psi into a bearing
    and flags sun-at-zenith / below-horizon cases. ``pitch_deg``/``roll_deg`` are the known tilt
    (tilt_aware), ``prior_bearing_deg`` an optional prior that resolves the 180 deg ambiguity.
    ``attitude_sigma_deg`` is the known tilt's 1-sigma uncertainty ``(pitch, roll)`` [deg] (IMU
    noise and bias, boresight, time offset x tilt rate): a method that reads the tilt adds ``J
    Sigma_att J^T`` (``J = d psi / d(pitch, roll)``) to its heading variance; None = the tilt is
    taken as exact.
    """

    aop_rad: np.ndarray
    dop: np.ndarray
    valid: np.ndarray
    rays_cam: np.ndarray
    x_px: np.ndarray
    y_px: np.ndarray
    camera: CameraModel
    sun_azimuth_deg: float
    sun_altitude_deg: float
    intensity: np.ndarray | None = None
    pitch_deg: float | None = None
    roll_deg: float | None = None
    prior_bearing_deg: float | None = None
    attitude_sigma_deg: tuple | None = None

    @staticmethod
    def from_frame(
        frame,
        pitch_deg=None,
        roll_deg=None,
        prior_bearing_deg=None,
        camera=None,
        attitude_sigma_deg=None,
    ) -> 'Observation':
        """
        Build an observation from a rendered frame (measured AoP/DoP when sensor effects ran).

        Parameters
        ----------
        frame : polarization_compass.render.Frame
            The frame: AoP [rad, eq 28], DoP, valid mask, camera-frame rays, eq 20 pixel
            coordinates, the sun (azimuth and geometric altitude [deg]) and metadata.
        pitch_deg, roll_deg : float, optional
            Known camera pitch and roll [deg] (eq 21), for tilt-aware methods.
        prior_bearing_deg : float, optional
            Prior bearing of camera +y [deg, clockwise from North] that resolves the 180 deg
            ambiguity.
        camera : CameraModel, optional
            The camera; by default the one in ``frame.meta["camera"]``, else the paper's imager.
        attitude_sigma_deg : tuple of float, optional
            1-sigma uncertainty ``(pitch, roll)`` of the known tilt [deg].

        Returns
        -------
        Observation
            The frame's arrays (not copied) with the sun, tilt and prior.

        """
        from ..scene import Scene  # noqa: F401  (documentation of origin)

        cam = (
            camera
            if camera is not None
            else CameraModel(**frame.meta['camera'])
            if 'camera' in frame.meta
            else CameraModel()
        )
        return Observation(
            frame.aop_rad,
            frame.dop,
            frame.valid,
            frame.rays_cam,
            frame.x_px,
            frame.y_px,
            cam,
            frame.sun.azimuth_deg,
            frame.sun.altitude_deg,
            frame.intensity,
            pitch_deg,
            roll_deg,
            prior_bearing_deg,
            attitude_sigma_deg,
        )


class Estimator:
    """
    Declare a heading method: the base class every estimator derives from.

    A subclass implements :meth:`estimate` and declares the facts about its method as class
    attributes, which everything else reads through :mod:`.registry`. ``knobs`` trade accuracy for
    time (stride, region, min_dop, window ...), described by :meth:`knob_specs`; ``pixels_needed``
    tells a renderer which pixels this method reads, so sweeps render only those.

    Parameters
    ----------
    **knobs
        The method's knobs (none here; subclasses validate them).

    Attributes
    ----------
    name : str
        The method's identifier (``--method``, node parameter ``method``, topic names, map files).
    label : str
        Human-readable name for figures and tables ("" = ``name``).
    style : tuple or None
        ``(matplotlib colour, line style)`` in figures (None = the next colour of the cycle).
    axial : bool
        The method alone knows the heading only modulo 180 deg.
    needs_tilt : bool
        Reads the known camera pitch and roll (``Observation.pitch_deg``/``roll_deg``): the
        pipeline waits for the IMU tilt at the image stamp, and the method runs without a tilt
        corrector (its raw heading is final, a "direct" method in graphs, the replay and the
        evaluator).
    paper_method : bool
        One of the paper's four approaches (default sets of ``sim``/``replay``/error maps, the
        paper's figures).
    sweep_knobs : dict
        Knobs an error-map sweep uses by default (its sampling: a sweep renders 1e4-1e5 frames, so
        it reads fewer pixels than a live estimate); {} = the method's defaults.
    accepts_units : bool
        The method also runs on a photodiode array's few unit E-vectors
        (:mod:`polarization_compass.photodiode.heading`); False: it needs an image.
    relative_cost : float
        CPU time per frame relative to the others (median ms per frame at the nodes' knobs, ``make
        bench`` group replay, 2026-11-24), used only to balance the replay's worker threads.

    """

    name = 'base'
    label = ''
    style: tuple | None = None
    axial = True
    needs_tilt = False
    paper_method = False
    sweep_knobs: dict = {}
    accepts_units = False
    relative_cost = 5.0

    def __init__(self, **knobs):
        self.knobs = dict(knobs)

    @classmethod
    def knob_specs(cls) -> dict:
        """
        Describe the knobs the method accepts (none here).

        Returns
        -------
        dict
            ``{knob name: Knob}``; empty for a method without knobs.

        """
        return {}

    def pixels_needed(self, camera: CameraModel) -> PixelSelection:
        """
        Tell a renderer which pixels the method reads (all here), so sweeps render only those.

        Parameters
        ----------
        camera : CameraModel
            The camera the frames come from.

        Returns
        -------
        PixelSelection
            The pixels to render.

        """
        return PixelSelection.full()

    def estimate(
        self, obs: Observation, sigma: bool = True
    ) -> HeadingResult:  # pragma: no cover - interface
        """
        Estimate one heading from an observation.

        ``sigma=False`` skips the uncertainty (``sigma_deg`` None, no residual statistics in
        ``extras``) for callers that use only psi and status (error-map sweeps): psi is the same as
        with ``sigma=True`` except that an unresolved (axial) result may name the other end of the
        meridian, which it does not know anyway; status and quality are the same.

        Parameters
        ----------
        obs : Observation
            AoP [rad, eq 28], DoP, rays (camera frame), the sun [deg] and optional tilt and prior.
        sigma : bool, default True
            Compute the 1-sigma uncertainty ``sigma_deg``.

        Returns
        -------
        HeadingResult
            psi [deg] (eq 21), bearing and REP-103 yaw, or a failure status with a reason; never
            NaN.

        """
        raise NotImplementedError

    @classmethod
    def tilt_sensitivity(cls, result: HeadingResult, pitch_deg: float, roll_deg: float):
        """
        Return how a result's psi moves with the known tilt it was estimated with.

        For methods that read the tilt (``needs_tilt``), the first-order ``(d psi / d pitch, d psi
        / d roll)`` [deg/deg] at the pitch and roll given, from which a caller that learns the
        tilt's uncertainty after the fact (the ``heading_estimator`` node: the IMU covariance)
        adds ``J Sigma_att J^T`` to the variance. Methods that do not read the tilt return None.

        Parameters
        ----------
        result : HeadingResult
            An ok result of this method.
        pitch_deg, roll_deg : float
            The camera pitch and roll [deg] (eq 21) it was estimated with.

        Returns
        -------
        tuple of float or None
            ``(d psi / d pitch, d psi / d roll)`` [deg/deg], or None.

        """
        return None
