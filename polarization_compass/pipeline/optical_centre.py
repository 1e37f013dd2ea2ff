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

Over a turn in place the offset does show: a fixed one is along the sun's image direction at some
yaws and across it at others, and ``calibrate-mount --camera`` fits it as a mount tilt of the same
axis and sign, though on a wide fisheye not of the same size (0.46-1.40 times ``atan(d / f)``, with
the sun; docs/real-cameras.md, "Limits"). :func:`mount_against_optical_centre` says so in that
command's report, and when the fitted mount leaves the camera file's stated one by more than the
mount's and the principal point's uncertainties allow, that the optical centre or the mount
disagrees with the sky.
"""

from __future__ import annotations

import math

__all__ = [
    'DEFAULT_PRINCIPAL_POINT_SIGMA_F',
    'focal_length_px',
    'MOUNT_PER_CENTRE_TILT_MAX',
    'mount_against_optical_centre',
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

#: the mount ``calibrate-mount --camera`` fits to a principal point ``d`` px off, as a multiple of
#: ``atan(d / f)``, at most: measured 0.46-1.40 on an equidistant fisheye of 80 deg field with the
#: sun 20-60 deg up, 0.81-1.03 with 40 deg of field (docs/real-cameras.md, "Limits")
MOUNT_PER_CENTRE_TILT_MAX = 1.4


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
        ``min(fx, fy)`` [px] of the camera's K (:meth:`~..camera.CameraModel.K_matrix`).

    """
    K = camera.K_matrix()
    return float(min(K[0, 0], K[1, 1]))


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


def mount_against_optical_centre(camera, stated_pp_px, stated_mount, fitted_mount) -> dict:
    """
    Compare a mount fitted from turns in place with the camera file's, as a tilt or a centre.

    To first order a mount of pitch ``p`` and roll ``r`` (eq 21: ``Rx(p) Ry(r)``) turns the nominal
    centre's ray onto the one a principal point ``(dx, dy) = (-f tan r, f tan p)`` px off would
    give it (``f`` :func:`focal_length_px`; in the sensor's image, after any readout flip). The
    fitted mount minus the stated one (level when none is stated) is reported as both. With a
    stated mount the difference is allowed, per axis, 3 sigma of the fit's, the stated mount's (0
    when not stated) and the principal point's (:func:`principal_point_sigma_px`, as a tilt,
    times :data:`MOUNT_PER_CENTRE_TILT_MAX`); beyond it the optical centre or the mount
    disagrees with the sky. Without a stated mount the fit is the mount's calibration and nothing
    is judged.

    Parameters
    ----------
    camera : CameraModel
        The camera of the camera file.
    stated_pp_px : float or None
        The principal point 1-sigma the camera file states [px]; None: the default.
    stated_mount : Mount or None
        The camera file's ``mount:`` (None: none stated).
    fitted_mount : Mount
        The fitted mount, with its sigmas.

    Returns
    -------
    dict
        ``tilt_deg`` (pitch, roll) the fitted minus the stated mount [deg];
        ``principal_point_equivalent_px`` (x, y) the centre offset it is equivalent to [px];
        ``allowed_deg`` (pitch, roll) what the uncertainties allow [deg], None without a stated
        mount; ``disagrees`` bool; ``lines`` the report's lines.

    """
    f_px = focal_length_px(camera)
    p0 = 0.0 if stated_mount is None else float(stated_mount.pitch_deg)
    r0 = 0.0 if stated_mount is None else float(stated_mount.roll_deg)
    dp = float(fitted_mount.pitch_deg) - p0
    dr = float(fitted_mount.roll_deg) - r0
    dx_px = -f_px * math.tan(math.radians(dr))
    dy_px = f_px * math.tan(math.radians(dp))
    lines = [
        f'the fitted tilt is also an optical centre off: a mount {dp:+.2f} deg of pitch and '
        f'{dr:+.2f} deg of roll from the stated one is to first order the principal point '
        f'{dx_px:+.1f} px in x and {dy_px:+.1f} px in y off (f {f_px:.1f} px; on a wide fisheye a '
        f'centre d px off gives 0.5-{MOUNT_PER_CENTRE_TILT_MAX:g} times atan(d / f) of mount, '
        'and the mount removes only part of its heading error: docs/real-cameras.md, "Limits")'
    ]
    out = {
        'tilt_deg': (dp, dr),
        'principal_point_equivalent_px': (dx_px, dy_px),
        'allowed_deg': None,
        'disagrees': False,
        'lines': lines,
    }
    if stated_mount is None:
        return out
    sigma_px, source = principal_point_sigma_px(camera, stated_pp_px)
    pp_deg = MOUNT_PER_CENTRE_TILT_MAX * principal_point_tilt_sigma_deg(camera, sigma_px)
    allowed = tuple(
        3.0 * math.hypot(fit or 0.0, stated or 0.0, pp_deg)
        for fit, stated in (
            (fitted_mount.pitch_sigma_deg, stated_mount.pitch_sigma_deg),
            (fitted_mount.roll_sigma_deg, stated_mount.roll_sigma_deg),
        )
    )
    out['allowed_deg'] = allowed
    if abs(dp) > allowed[0] or abs(dr) > allowed[1]:
        out['disagrees'] = True
        lines.append(
            "the camera's optical centre or mount disagrees with the sky: the fitted mount "
            f'(pitch {fitted_mount.pitch_deg:.2f}, roll {fitted_mount.roll_deg:.2f} deg) is '
            f"{dp:+.2f}, {dr:+.2f} deg from the camera file's ({p0:.2f}, {r0:.2f} deg), beyond "
            f'the {allowed[0]:.2f}, {allowed[1]:.2f} deg its mount, principal point ({source} '
            f'sigma {sigma_px:.2f} px) and fit allow (3 sigma). If the camera sits as stated, '
            'calibrate its intrinsics (the principal point); if not, keep the fitted mount'
        )
    return out
