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
The principal point's uncertainty in a heading's sigma, as the camera tilt it is equivalent to.

To first order a principal point ``d`` pixels off is the optical axis turned by ``atan(d / f)``
(``f`` the focal length in pixels; for a fisheye the lens model's local scale at the centre): a
camera tilt. The sky cannot tell that tilt apart from a true one, and half of it not even from the
heading: the single-scattering AoP field ``E = S x P`` depends on the sun's direction in the camera
frame only, so a turn of the camera about the sun's direction is invisible, and a tilt ``e``
about the horizontal axis towards the sun is that invisible turn plus a heading change of ``e tan
h`` (``h`` the sun altitude). A principal point off *across* the sun's image direction therefore
moves the heading while no fit of the sky can see it (measured in docs/real-cameras.md, "Limits").
What is left is to say how well the principal point is known: :func:`with_principal_point_sigma`
grows a heading's sigma by ``|J| atan(sigma_pp / f)``, ``J`` the heading's first-order response to
a camera tilt at the known sun (:func:`~..estimators.sun_from_evectors.tilt_sensitivity`), with
``sigma_pp`` the calibration's stated 1-sigma or, when nothing states one,
:data:`DEFAULT_PRINCIPAL_POINT_SIGMA_F` of the focal length.

:func:`~.front_end.estimate_checked` calls it on every result, so ``estimate``, the
``heading_estimator`` node and ``replay`` take the same share.
"""

from __future__ import annotations

import math

__all__ = [
    'DEFAULT_PRINCIPAL_POINT_SIGMA_F',
    'focal_length_px',
    'principal_point_sigma_px',
    'principal_point_tilt_sigma_deg',
    'with_principal_point_sigma',
]

#: a calibration's principal point 1-sigma as a fraction of the focal length, used when nothing
#: states one: 0.5 % (0.29 deg of equivalent tilt). A checkerboard calibration reports 0.03-0.35 %
#: (Bouguet's Camera Calibration Toolbox, whose ``+-`` is 3 sigma: cc +- 0.6 px at fc 657 px in its
#: first example; cc +- [22, 15] px at fc 2100 px from 27 views in a user's report), and a repeated
#: calibration moves the principal point by more than its formal sigma; 0.5 % covers the upper end.
DEFAULT_PRINCIPAL_POINT_SIGMA_F = 0.005


def focal_length_px(camera) -> float:
    """
    Return the camera's focal length in pixels, the smaller of x and y.

    For the pinhole model the focal length; for the equidistant fisheye (``r = f theta``) and the
    OpenCV distortion models the lens' local scale at the principal point [px/rad].

    Parameters
    ----------
    camera : CameraModel
        The camera.

    Returns
    -------
    float
        ``min(fx, fy)`` [px].

    """
    return camera.focal_length_mm * 1e3 / max(camera.pixel_pitch_x_um, camera.pixel_pitch_y_um)


def principal_point_sigma_px(camera, stated_px=None) -> tuple[float, str]:
    """
    Return the principal point's 1-sigma [px] and where it comes from.

    Parameters
    ----------
    camera : CameraModel
        The camera.
    stated_px : float or None, optional
        The 1-sigma the calibration states [px] (``principal_point_sigma_px`` of CAMERA.yaml or
        the node's parameter); None or negative: not stated.

    Returns
    -------
    sigma_px : float
        The stated value, else :data:`DEFAULT_PRINCIPAL_POINT_SIGMA_F` x :func:`focal_length_px`.
    source : {"stated", "default"}
        Where it comes from.

    """
    if stated_px is not None and stated_px >= 0.0:
        return float(stated_px), 'stated'
    return DEFAULT_PRINCIPAL_POINT_SIGMA_F * focal_length_px(camera), 'default'


def principal_point_tilt_sigma_deg(camera, sigma_px: float) -> float:
    """
    Return the camera tilt [deg] a principal point error of ``sigma_px`` is equivalent to.

    ``atan(sigma_px / f)`` with ``f`` :func:`focal_length_px`.

    Parameters
    ----------
    camera : CameraModel
        The camera.
    sigma_px : float
        Principal point 1-sigma [px].

    Returns
    -------
    float
        The equivalent tilt 1-sigma [deg].

    """
    return math.degrees(math.atan2(float(sigma_px), focal_length_px(camera)))


def with_principal_point_sigma(
    result, camera, stated_px, sun_altitude_deg: float, pitch_deg=None, roll_deg=None
):
    """
    Grow a heading's sigma by the principal point's uncertainty, as an equivalent camera tilt.

    The heading's response to a tilt ``J = (d psi / d pitch, d psi / d roll)`` is that of the sun's
    azimuth in the levelled camera frame, at the result's psi, the known sun altitude and the
    camera's pitch and roll (:func:`~..estimators.sun_from_evectors.tilt_sensitivity`); the share
    is ``|J| * sigma_tilt`` with ``sigma_tilt`` :func:`principal_point_tilt_sigma_deg` (isotropic:
    the principal point is as uncertain in x as in y). Only a result with a heading and a sigma
    whose status is ``ok`` or ``ambiguous``.

    Parameters
    ----------
    result : HeadingResult
        The method's result.
    camera : CameraModel
        The camera the observation was made with.
    stated_px : float or None
        The principal point 1-sigma the calibration states [px]; None or negative: the default
        (:func:`principal_point_sigma_px`); 0: exact (a rendered frame's own camera).
    sun_altitude_deg : float
        The known sun altitude [deg].
    pitch_deg, roll_deg : float, optional
        The camera pitch and roll [deg] (eq 21); None: level.

    Returns
    -------
    HeadingResult
        ``result`` itself, or a copy whose ``sigma_deg`` is ``hypot(sigma, share)`` and whose
        extras hold ``sigma_principal_point_deg`` (the share [deg]), ``principal_point_sigma_px``
        and ``principal_point_sigma_source`` (``stated`` or ``default``).

    """
    import dataclasses

    from ..estimators.base import Status
    from ..estimators.sun_from_evectors import tilt_sensitivity
    from ..skyfit import _sun_cam

    if (
        camera is None
        or result.psi_deg is None
        or result.sigma_deg is None
        or result.status not in (Status.OK, Status.AMBIGUOUS)
    ):
        return result
    sigma_px, source = principal_point_sigma_px(camera, stated_px)
    if sigma_px == 0.0:
        return result
    pitch = 0.0 if pitch_deg is None else float(pitch_deg)
    roll = 0.0 if roll_deg is None else float(roll_deg)
    sun = _sun_cam([float(result.psi_deg)], [float(sun_altitude_deg)], pitch, roll)[0]
    jp, jr = tilt_sensitivity(sun, pitch, roll)
    share = math.hypot(jp, jr) * principal_point_tilt_sigma_deg(camera, sigma_px)
    return dataclasses.replace(
        result,
        sigma_deg=math.hypot(result.sigma_deg, share),
        extras={
            **result.extras,
            'sigma_principal_point_deg': share,
            'principal_point_sigma_px': sigma_px,
            'principal_point_sigma_source': source,
        },
    )
