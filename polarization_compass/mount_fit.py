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
Mount calibration of a photodiode array or a camera from turns in place with an IMU (issue 28).

Through a turn in place the sun's azimuth in the body frame turns exactly with the IMU's yaw: the
body's bearing is ``c_k - degrees(imu_yaw)`` with one unknown offset ``c_k`` per turn (an IMU is
re-zeroed between turns). The mount pitch and roll (:mod:`.mount`), shared by all turns, and the
offsets are the parameters under which every unit's measured angle of polarization fits the
single-scattering sky of the ephemeris sun (eq 18, ``E = S x P``, read as the unit reads it: the
forward model of :func:`~.conventions.unit_angle_from_evector_body_rad` on the sensor frame of
:func:`~.mount.sun_sensor`; for a camera, :class:`CameraRays`, the eq 28 AoP of fixed pixel
rays). A robust (soft L1) least-squares fit with DoP^2 weights, the estimators' weighting; its
1-sigmas are the larger of the Gauss-Newton covariance scaled by the
residuals and, with 4 turns or more, the same covariance clustered by turn (residuals of one turn
share the sky's misfit). The fit refuses, in one line naming what is missing, turns that cannot
determine the mount: too few usable samples, too little rotation, the sun too low, or sigmas
above ``max_sigma_deg``.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .conventions import (
    aop_from_evector_cam_rad,
    enu_direction,
    fold_axial_rad,
    unit_angle_from_evector_body_rad,
    unit_axis_body,
)
from .errors import CompassError
from .mount import Mount, R_enu_sensor_cam, sun_sensor

__all__ = [
    'MountFitError',
    'TurnSamples',
    'MountFit',
    'turn_samples',
    'camera_samples',
    'CameraRays',
    'concat',
    'predicted_aop_rad',
    'fit_mount',
]

#: soft-L1 scale of the angle residuals [deg]
ROBUST_SCALE_DEG = 10.0

#: scattering angles [deg] (sun to a unit's view) where a clear sky's angle of polarization is the
#: single-scattering one: the neutral points (Arago, Babinet, Brewster) and the low degree of
#: polarization lie within about 30 deg of the sun and the antisun; the sky misfit is read here
SKY_BAND_DEG = (60.0, 120.0)


class MountFitError(CompassError):
    """Turns that cannot determine the mount (the message says what is missing)."""


@dataclass
class TurnSamples:
    """
    Per-sample inputs of the fit, one row per sample (flattened over recordings).

    ``aop_rad`` and ``w`` (S, U): measured angles and DoP^2 weights (0: unit not usable);
    ``imu_yaw_rad``, ``sun_azimuth_deg``, ``sun_altitude_deg``, ``pitch_deg``, ``roll_deg`` (S,);
    ``turn`` (S,) integer turn label, unique over all recordings.
    """

    aop_rad: np.ndarray
    w: np.ndarray
    imu_yaw_rad: np.ndarray
    sun_azimuth_deg: np.ndarray
    sun_altitude_deg: np.ndarray
    pitch_deg: np.ndarray
    roll_deg: np.ndarray
    turn: np.ndarray


@dataclass
class MountFit:
    """
    The fitted mount (sigmas set) and the per-turn IMU offsets [deg] with the residuals.

    ``spread``: the factors the recordings' disagreement widened the mount's sigmas by (pitch,
    roll; :func:`fit_mount_recordings`); ``warning`` one line when they disagree ('' otherwise).
    ``sky_misfit_deg``: how well the sky fits the single-scattering model: the median over
    samples of each sample's DoP^2-weighted rms angle residual at the fitted mount, over the units
    viewing the sky 60-120 deg from the sun (``SKY_BAND_DEG``; nan when none does).
    ``used``, ``left_out``: the recordings (1-based) fitted and left out by the sky gate of
    :func:`~.mount_recordings.fit_mount_recordings` (empty for :func:`fit_mount` alone).
    """

    mount: Mount
    yaw_offsets_deg: np.ndarray
    yaw_offsets_sigma_deg: np.ndarray
    turns: int
    samples: int
    angle_rms_before_deg: float
    angle_rms_after_deg: float
    spread: tuple = (1.0, 1.0)
    warning: str = ''
    sky_misfit_deg: float = math.nan
    used: tuple = ()
    left_out: tuple = ()


def turn_samples(
    stokes,
    geometry,
    imu_yaw_rad,
    turn,
    sun_az_deg,
    sun_alt_deg,
    pitch_deg=0.0,
    roll_deg=0.0,
    min_dop: float = 0.02,
) -> TurnSamples:
    """
    Collect the fit's inputs from the units' Stokes fit of a recording.

    Parameters
    ----------
    stokes : UnitStokes
        :func:`~.photodiode.stokes.fit_stokes` of the readings, arrays (S, U).
    geometry : ArrayGeometry
        The sensor description (enabled units).
    imu_yaw_rad, turn, sun_az_deg, sun_alt_deg : array_like
        (S,) IMU yaw [rad, counter-clockwise], turn label, ephemeris sun [deg].
    pitch_deg, roll_deg : float or array_like, optional
        The body's pitch and roll [deg] (the IMU's; 0: level).
    min_dop : float, optional
        Units seeing a lower DoP are not used.

    Returns
    -------
    TurnSamples
        The samples, weights ``min(DoP, 1)^2`` on usable units, 0 elsewhere.

    """
    S = stokes.aop_rad.shape[0]
    enabled = np.array([u.enabled for u in geometry.units])
    dop = np.asarray(stokes.dop, dtype=float)
    ok = stokes.valid & enabled[None, :] & np.isfinite(stokes.aop_rad) & np.isfinite(dop)
    ok &= dop >= min_dop
    w = np.where(ok, np.minimum(np.nan_to_num(dop), 1.0) ** 2, 0.0)

    def per(v):
        return np.broadcast_to(np.asarray(v, dtype=float), (S,)).copy()

    return TurnSamples(
        np.where(ok, stokes.aop_rad, 0.0),
        w,
        per(imu_yaw_rad),
        per(sun_az_deg),
        per(sun_alt_deg),
        per(pitch_deg),
        per(roll_deg),
        np.asarray(turn, dtype=np.int64),
    )


def concat(parts: list) -> TurnSamples:
    """
    Join the samples of several recordings (their turn labels must already be distinct).

    Parameters
    ----------
    parts : list of TurnSamples
        The recordings' samples.

    Returns
    -------
    TurnSamples
        All samples.

    """
    return TurnSamples(
        *(
            np.concatenate([getattr(p, f) for p in parts])
            for f in (
                'aop_rad',
                'w',
                'imu_yaw_rad',
                'sun_azimuth_deg',
                'sun_altitude_deg',
                'pitch_deg',
                'roll_deg',
                'turn',
            )
        )
    )


def predicted_aop_rad(geometry, d: TurnSamples, bearing_deg, mount: Mount | None) -> np.ndarray:
    """
    Return the angle each unit reads under a Rayleigh sky, for given body bearings and mount.

    Parameters
    ----------
    geometry : ArrayGeometry
        The units (their description is the sensor frame; the geometry's own mount is ignored).
    d : TurnSamples
        Sun and body pitch/roll per sample.
    bearing_deg : array_like
        (S,) true bearing of the body's front [deg].
    mount : Mount or None
        The mount to compose with the body's attitude.

    Returns
    -------
    numpy.ndarray
        (S, U) angles [rad] in the units' convention.

    References
    ----------
    The paper's eq 18 (``E = S x P``) and eq 21 (attitude).

    """
    az = np.array([u.azimuth_deg for u in geometry.units])
    el = np.array([u.elevation_deg for u in geometry.units])
    s = sun_sensor(
        d.sun_azimuth_deg, d.sun_altitude_deg, bearing_deg, d.pitch_deg, d.roll_deg, mount
    )
    e = np.cross(s[:, None, :], unit_axis_body(az, el)[None, :, :])
    return unit_angle_from_evector_body_rad(e, az, el, geometry.angle_zero, geometry.angle_sense)


@dataclass(frozen=True)
class CameraRays:
    """
    The pixel rays of a camera whose angles of polarization (eq 28) the fit reads.

    ``rays_cam`` (P, 3) unit rays in the camera frame (``SelectedPixels.rays_cam.T``).
    """

    rays_cam: np.ndarray

    def predict_aop_rad(self, d: TurnSamples, bearing_deg, mount: Mount | None) -> np.ndarray:
        """
        Return the eq 28 AoP of each ray under a Rayleigh sky for given body bearings and mount.

        Parameters
        ----------
        d : TurnSamples
            Sun and body pitch/roll per frame.
        bearing_deg : array_like
            (S,) true bearing of the body's front [deg] (camera +y on a level mount).
        mount : Mount or None
            The camera's mount, composed with the body attitude (:func:`.mount.R_enu_sensor_cam`).

        Returns
        -------
        numpy.ndarray
            (S, P) AoP [rad].

        """
        R = R_enu_sensor_cam(bearing_deg, d.pitch_deg, d.roll_deg, mount)
        s_cam = np.einsum('sji,sj->si', R, enu_direction(d.sun_azimuth_deg, d.sun_altitude_deg))
        e = np.cross(s_cam[:, None, :], np.asarray(self.rays_cam)[None, :, :])
        return aop_from_evector_cam_rad(e)


def camera_samples(
    aop_rad,
    dop,
    valid,
    imu_yaw_rad,
    turn,
    sun_az_deg,
    sun_alt_deg,
    pitch_deg=0.0,
    roll_deg=0.0,
    min_dop: float = 0.02,
) -> TurnSamples:
    """
    Collect the fit's inputs from camera frames sampled at fixed pixels.

    Parameters
    ----------
    aop_rad, dop, valid : array_like
        (S, P) the frames' AoP [rad, eq 28], DoP and validity at the rays of :class:`CameraRays`.
    imu_yaw_rad, turn, sun_az_deg, sun_alt_deg : array_like
        (S,) IMU yaw [rad, counter-clockwise], turn label, ephemeris sun [deg].
    pitch_deg, roll_deg : float or array_like, optional
        The body's pitch and roll [deg].
    min_dop : float, optional
        Pixels with a lower DoP are not used.

    Returns
    -------
    TurnSamples
        The samples, weights ``min(DoP, 1)^2`` on usable pixels.

    """
    aop = np.asarray(aop_rad, dtype=float)
    dop = np.asarray(dop, dtype=float)
    ok = np.asarray(valid, dtype=bool) & np.isfinite(aop) & np.isfinite(dop) & (dop >= min_dop)
    S = aop.shape[0]

    def per(v):
        return np.broadcast_to(np.asarray(v, dtype=float), (S,)).copy()

    return TurnSamples(
        np.where(ok, aop, 0.0),
        np.where(ok, np.minimum(np.nan_to_num(dop), 1.0) ** 2, 0.0),
        per(imu_yaw_rad),
        per(sun_az_deg),
        per(sun_alt_deg),
        per(pitch_deg),
        per(roll_deg),
        np.asarray(turn, dtype=np.int64),
    )


class _Problem:
    """The residual function of the fit: x = (mount pitch, mount roll, c_0 .. c_K-1) [deg]."""

    def __init__(self, geometry, d: TurnSamples):
        self.geometry, self.d = geometry, d
        if isinstance(geometry, CameraRays):
            self.predict = geometry.predict_aop_rad
        else:
            self.predict = lambda d_, b, m: predicted_aop_rad(geometry, d_, b, m)
        self.labels, self.k = np.unique(d.turn, return_inverse=True)
        self.sqrt_w = np.sqrt(d.w)
        self.use = d.w > 0  # (S, U)

    def bearings(self, offsets_deg) -> np.ndarray:
        return np.asarray(offsets_deg)[self.k] - np.degrees(self.d.imu_yaw_rad)

    def angle_residuals_rad(self, x) -> np.ndarray:
        """Return the (S, U) folded angle residuals [rad] (0 where a unit is not usable)."""
        m = Mount(float(x[0]), float(x[1]))
        pred = self.predict(self.d, self.bearings(x[2:]), m)
        return np.where(self.use, fold_axial_rad(self.d.aop_rad - pred), 0.0)

    def __call__(self, x) -> np.ndarray:
        return (self.sqrt_w * self.angle_residuals_rad(x))[self.use]

    def sparsity(self):
        from scipy.sparse import lil_matrix

        rows = np.nonzero(self.use)[0]  # sample of each residual, in __call__'s order
        J = lil_matrix((rows.size, 2 + self.labels.size), dtype=int)
        J[:, :2] = 1
        J[np.arange(rows.size), 2 + self.k[rows]] = 1
        return J

    def scattering_angle_deg(self, x) -> np.ndarray:
        """Return the (S, U) angle [deg] between the sun and each unit's (or ray's) view."""
        b, m = self.bearings(x[2:]), Mount(float(x[0]), float(x[1]))
        if isinstance(self.geometry, CameraRays):
            R = R_enu_sensor_cam(b, self.d.pitch_deg, self.d.roll_deg, m)
            sun = enu_direction(self.d.sun_azimuth_deg, self.d.sun_altitude_deg)
            s = np.einsum('sji,sj->si', R, sun)
            view = np.asarray(self.geometry.rays_cam)
        else:
            s = sun_sensor(
                self.d.sun_azimuth_deg,
                self.d.sun_altitude_deg,
                b,
                self.d.pitch_deg,
                self.d.roll_deg,
                m,
            )
            az = np.array([u.azimuth_deg for u in self.geometry.units])
            el = np.array([u.elevation_deg for u in self.geometry.units])
            view = unit_axis_body(az, el)
        return np.degrees(np.arccos(np.clip(s @ view.T, -1.0, 1.0)))

    def sky_misfit_deg(self, x) -> float:
        """Return the median over samples of the rms residual [deg] of units in the sky band."""
        lo, hi = SKY_BAND_DEG
        gamma = self.scattering_angle_deg(x)
        w = np.where((gamma >= lo) & (gamma <= hi), self.d.w, 0.0)
        rows = np.sum(w > 0, axis=1) >= 1
        if not rows.any():
            return math.nan
        r2 = self.angle_residuals_rad(x)[rows] ** 2
        w = w[rows]
        return math.degrees(float(np.median(np.sqrt(np.sum(w * r2, axis=1) / np.sum(w, axis=1)))))

    def rms_deg(self, x) -> float:
        r = self.angle_residuals_rad(x)
        return math.degrees(math.sqrt(float(np.sum(self.d.w * r**2)) / float(np.sum(self.d.w))))


def _check_observable(
    d: TurnSamples, min_samples: int, min_rotation_deg: float, min_sun_altitude_deg: float
) -> None:
    """Refuse (one line, what is missing) turns that cannot determine the mount."""
    used = np.sum(d.w > 0, axis=1) >= 3
    n = int(used.sum())
    if n < min_samples:
        raise MountFitError(
            f'cannot calibrate the mount: {n} samples with 3 or more usable units, need '
            f'{min_samples} (record longer turns, or check the geometry and the readings)'
        )
    rot = max(_rotation_deg(d.imu_yaw_rad[used & (d.turn == t)]) for t in np.unique(d.turn))
    if rot < min_rotation_deg:
        raise MountFitError(
            f'cannot calibrate the mount: the turns rotate at most {rot:.0f} deg of IMU yaw, '
            f'need {min_rotation_deg:.0f} deg in one turn (turn a full circle in place; '
            'the recording needs imu_yaw_rad)'
        )
    alt = float(np.median(d.sun_altitude_deg[used]))
    if alt < min_sun_altitude_deg:
        raise MountFitError(
            f'cannot calibrate the mount: the sun is at {alt:.1f} deg (median), need '
            f'{min_sun_altitude_deg:.0f} deg or higher (a tilt barely shows with a low sun: '
            'record the turn nearer noon)'
        )


def _rotation_deg(yaw_rad) -> float:
    """Return the yaw coverage of one turn [deg]: 30 deg bins of yaw (mod 360) visited."""
    if yaw_rad.size == 0:
        return 0.0
    bins = np.floor(np.degrees(yaw_rad) % 360.0 / 30.0).astype(int)
    return 30.0 * np.unique(bins).size


def _initial_offsets(prob: _Problem) -> np.ndarray:
    """Per turn, the offset [deg] on a 5 deg grid with the least robust cost, level mount."""
    grid = np.arange(0.0, 360.0, 5.0)
    best = np.zeros(prob.labels.size)
    for j in range(prob.labels.size):
        rows = prob.k == j
        costs = []
        for c in grid:
            x = np.r_[0.0, 0.0, np.full(prob.labels.size, c)]
            r = prob.angle_residuals_rad(x)[rows] / math.radians(ROBUST_SCALE_DEG)
            costs.append(float(np.sum(prob.d.w[rows] * (np.sqrt(1.0 + r**2) - 1.0))))
        best[j] = grid[int(np.argmin(costs))]
    return best


def _sigmas_deg(prob: _Problem, sol) -> np.ndarray:
    """
    Return the parameters' 1-sigmas [deg] (module doc: scaled and, from 4 turns, clustered).

    The robust fit is read as its last reweighted least squares: weights ``rho'`` of soft L1.
    """
    J = sol.jac.toarray() if hasattr(sol.jac, 'toarray') else np.asarray(sol.jac)
    z = (sol.fun / math.radians(ROBUST_SCALE_DEG)) ** 2
    f = sol.fun * (1.0 + z) ** -0.25  # sqrt(rho') f
    m, n = J.shape
    bread = np.linalg.pinv(J.T @ J)
    var = np.diag(bread) * float(f @ f) / max(m - n, 1)
    K = prob.labels.size
    if K >= 4:
        rows = np.nonzero(prob.use)[0]
        g = np.zeros((K, n))
        np.add.at(g, prob.k[rows], J * f[:, None])
        var = np.maximum(var, np.diag(bread @ (g.T @ g) @ bread) * K / (K - 1))
    return np.sqrt(np.maximum(var, 0.0))  # x is in degrees


def fit_mount(
    geometry,
    d: TurnSamples,
    min_samples: int = 20,
    min_rotation_deg: float = 270.0,
    min_sun_altitude_deg: float = 10.0,
    max_sigma_deg: float = 3.0,
) -> MountFit:
    """
    Fit the mount pitch and roll (shared) and one IMU yaw offset per turn (module doc).

    Parameters
    ----------
    geometry : ArrayGeometry or CameraRays
        The sensor: an array's description (its own mount, if any, is not used: the fit starts
        level) or a camera's pixel rays.
    d : TurnSamples
        The turns' samples (:func:`turn_samples`, :func:`camera_samples`, :func:`concat`).
    min_samples : int, optional
        Samples with 3 or more usable units needed.
    min_rotation_deg : float, optional
        IMU yaw coverage one turn must reach [deg] (30 deg bins).
    min_sun_altitude_deg : float, optional
        Median sun altitude needed [deg].
    max_sigma_deg : float, optional
        A mount sigma above this [deg]: refused as undetermined.

    Returns
    -------
    MountFit
        The mount with its sigmas, the offsets and the angle residuals before/after.

    Raises
    ------
    MountFitError
        One line saying what the turns lack.

    """
    from scipy.optimize import least_squares

    _check_observable(d, min_samples, min_rotation_deg, min_sun_altitude_deg)
    prob = _Problem(geometry, d)
    x0 = np.r_[0.0, 0.0, _initial_offsets(prob)]
    level = least_squares(
        lambda c: prob(np.r_[0.0, 0.0, c]),
        x0[2:],
        loss='soft_l1',
        f_scale=math.radians(ROBUST_SCALE_DEG),
        jac_sparsity=prob.sparsity()[:, 2:],
    )
    sol = least_squares(
        prob,
        np.r_[0.0, 0.0, level.x],
        loss='soft_l1',
        f_scale=math.radians(ROBUST_SCALE_DEG),
        jac_sparsity=prob.sparsity(),
        x_scale=1.0,
    )
    sig = _sigmas_deg(prob, sol)
    if max(sig[0], sig[1]) > max_sigma_deg:
        raise MountFitError(
            f'cannot calibrate the mount: the turns leave it undetermined (sigma pitch '
            f'{sig[0]:.1f}, roll {sig[1]:.1f} deg > {max_sigma_deg:g}); add turns with a higher '
            'sun or a clearer sky'
        )
    m = Mount(float(sol.x[0]), float(sol.x[1]), float(sig[0]), float(sig[1]))
    return MountFit(
        m,
        np.asarray(sol.x[2:]) % 360.0,
        sig[2:],
        int(prob.labels.size),
        int(np.sum(np.sum(d.w > 0, axis=1) >= 3)),
        prob.rms_deg(np.r_[0.0, 0.0, level.x]),
        prob.rms_deg(sol.x),
        sky_misfit_deg=prob.sky_misfit_deg(sol.x),
    )
