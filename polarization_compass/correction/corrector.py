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
The tilt corrector of one method: :class:`TiltCorrector` and the shipped map's location.

Its derivatives with respect to the attitude (``error_gradient``, ``heading_sensitivity``,
``attitude_sigma_deg``) are inherited from :mod:`.sensitivity`.
"""

from __future__ import annotations

from importlib import resources
import math
from pathlib import Path

import numpy as np

from .kernels import _accumulate_curves, _invert_kernel
from .results import _FROM_INT, BearingCorrections, Correction, CorrectionStatus, STATUS_INT
from .sensitivity import _AttitudeSensitivity
from .weights import _axis_weights, _is_uniform, _yaw_weights
from ..conventions import psi_to_bearing_deg, wrap_180_deg
from ..errormap import ErrorMap, ErrorMapError
from ..errormap_io import load_error_map

DEFAULT_MAP_NAME = 'tilt_error_map.npz'
#: The command that regenerates the shipped map (documented in docs/error-maps.md).
REGENERATE_DEFAULT_MAP = (
    'polarization-compass errormap --methods zenith,sm_asm,symmetry,least_squares '
    '--sun-altitude 0:50:5 --yaw -180:175:5 --pitch -30:30:5 --roll -30:30:5 '
    '--float32 --out polarization_compass/data/tilt_error_map.npz'
)

#: Roots listed per query (a yaw search window of 180 deg holds a handful at most).
_MAX_ROOTS = 16


def default_map_path() -> Path:
    """
    Locate the shipped error map.

    Returns
    -------
    pathlib.Path
        ``polarization_compass/data/tilt_error_map.npz`` inside the installed package.

    """
    return Path(str(resources.files('polarization_compass').joinpath('data/' + DEFAULT_MAP_NAME)))


# --------------------------------------------------------------------------------------------
# The corrector
# --------------------------------------------------------------------------------------------
class TiltCorrector(_AttitudeSensitivity):
    """
    Correct one method's headings with a tilt error map.

    Parameters
    ----------
    error_map : ErrorMap
        The map; its yaw axis must have a uniform step and cover a full turn.
    method : str
        The method whose errors to use (a name in the map).
    order : {3, 1}, default 3
        Interpolation: cubic convolution (Keys, a = -1/2) or multilinear.

    Raises
    ------
    ErrorMapError
        Bad order, a method not in the map, or a yaw axis that is not a uniform full turn.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), Sec. 3.4 (correcting the
       tilt error with the simulated errors).
    .. [2] R. Keys, "Cubic convolution interpolation for digital image processing", IEEE
       Transactions on Acoustics, Speech, and Signal Processing 29(6): 1153-1160, 1981.

    """

    def __init__(self, error_map: ErrorMap, method: str, order: int = 3):
        if order not in (1, 3):
            raise ErrorMapError(f'interpolation order must be 1 or 3, got {order}')
        self.map = error_map
        self.method = method
        self.order = order
        m = error_map.method_index(method)
        yaw = error_map.yaw_deg
        if yaw.size < 4 or not _is_uniform(yaw):
            raise ErrorMapError(
                'correction needs a map whose yaw axis has a uniform step and covers a full turn'
            )
        step = float(yaw[1] - yaw[0])
        n_turn = 360.0 / step
        if abs(n_turn - round(n_turn)) > 1e-6:
            raise ErrorMapError(f'the yaw step {step:g} deg does not divide 360 deg')
        n_turn = int(round(n_turn))
        if yaw.size == n_turn + 1 and abs(yaw[-1] - yaw[0] - 360.0) < 1e-6:
            keep = slice(0, n_turn)  # last node repeats the first
        elif yaw.size == n_turn:
            keep = slice(0, n_turn)
        else:
            raise ErrorMapError(
                f'correction needs a map whose yaw axis covers a full turn '
                f'(it has {yaw[0]:g}..{yaw[-1]:g} in steps of {step:g})'
            )
        self.yaw0 = float(yaw[0])
        self.yaw_step = step
        self.n_yaw = n_turn
        self.E = np.ascontiguousarray(error_map.error_deg[m][:, keep])  # (A, Y, P, R)
        self.V = np.ascontiguousarray(error_map.valid[m][:, keep])
        self.alt = error_map.sun_altitude_deg
        self.pitch = error_map.pitch_deg
        self.roll = error_map.roll_deg
        dom = error_map.meta.get('domain', {}) if isinstance(error_map.meta, dict) else {}
        self.full_domain = bool(dom.get('full_domain', False))
        self.tilt_limit_deg = float(dom.get('tilt_limit_deg', math.inf))
        # compile (or load from numba's cache) the kernels now, not on the first heading a node
        # corrects
        self._correct(0.0, float(self.alt[0]), float(self.pitch[0]), float(self.roll[0]), 'invert')

    @staticmethod
    def from_file(path=None, method: str = 'least_squares', order: int = 3) -> 'TiltCorrector':
        """
        Build a corrector from a map file (default: the shipped map).

        Parameters
        ----------
        path : str or os.PathLike, optional
            The ``.npz`` error map; :func:`default_map_path` when None.
        method : str, default "least_squares"
            The method whose errors to use.
        order : {3, 1}, default 3
            Interpolation order.

        Returns
        -------
        TiltCorrector
            The corrector.

        Raises
        ------
        ErrorMapError
            The file is missing, corrupt or unusable for correction.

        """
        return TiltCorrector(
            load_error_map(default_map_path() if path is None else path), method, order
        )

    # ------------------------------------------------------------------------------------------
    def _tilt_weights(self, h, p, r, order):
        ia, wa, in_a = _axis_weights(self.alt, h, order)
        ip, wp, in_p = _axis_weights(self.pitch, p, order)
        ir, wr, in_r = _axis_weights(self.roll, r, order)
        inside = in_a & in_p & in_r
        if not self.full_domain:
            inside &= (np.abs(p) + np.abs(r)) <= self.tilt_limit_deg + 1e-9
        return (ia, wa), (ip, wp), (ir, wr), inside

    def _curves_order(self, h, p, r, order):
        """Error curves over the yaw nodes (N, Y), their validity (N,), and inside (N,)."""
        (ia, wa), (ip, wp), (ir, wr), inside = self._tilt_weights(h, p, r, order)
        ok = inside.copy()
        out = _accumulate_curves(
            self.E, self.V, *(np.ascontiguousarray(v) for v in (ia, wa, ip, wp, ir, wr)), ok
        )
        return out, ok, inside

    def curves(self, h, p, r):
        """
        Interpolate the error at every yaw node for each (sun altitude, pitch, roll) query.

        Cubic where every node of the stencil is valid, else multilinear in the cell, else invalid.

        Parameters
        ----------
        h : float or array_like
            Sun altitude [deg].
        p, r : float or array_like
            Camera pitch and roll [deg] (eq 21), broadcast with ``h``.

        Returns
        -------
        curves : numpy.ndarray
            Error [deg] at the map's yaw nodes, shape (N, Y).
        ok : numpy.ndarray
            bool (N,): the query is inside the domain and every node it reads is valid.

        References
        ----------
        .. [1] R. Keys, "Cubic convolution interpolation for digital image processing", IEEE
           Transactions on Acoustics, Speech, and Signal Processing 29(6): 1153-1160, 1981.

        """
        h, p, r = (np.atleast_1d(np.asarray(v, dtype=float)) for v in np.broadcast_arrays(h, p, r))
        c, ok, inside = self._curves_order(h, p, r, self.order)
        if self.order == 3 and not ok.all():
            bad = ~ok & inside
            if bad.any():
                c1, ok1, _ = self._curves_order(h[bad], p[bad], r[bad], 1)
                c[bad] = c1
                ok[bad] = ok1
        return c, ok

    def _eval_on_curve(self, curve, rows, psi, deriv: bool = False):
        idx, w = _yaw_weights(self.yaw0, self.yaw_step, self.n_yaw, psi, self.order, deriv)
        return np.sum(curve[rows[..., None], idx] * w, axis=-1)

    def predicted_error(self, psi_true_deg, h_deg, pitch_deg, roll_deg):
        """
        Interpolate the map's heading error at given true yaws.

        Parameters
        ----------
        psi_true_deg : float or array_like
            True yaw psi [deg] (eq 21).
        h_deg : float or array_like
            Sun altitude [deg].
        pitch_deg, roll_deg : float or array_like
            Camera pitch alpha and roll beta [deg] (eq 21), broadcast together.

        Returns
        -------
        error_deg : numpy.ndarray
            ``psi_meas - psi`` [deg], shape (N,); 0 where not ok.
        ok : numpy.ndarray
            bool (N,).

        """
        psi, h, p, r = (
            np.atleast_1d(np.asarray(v, dtype=float))
            for v in np.broadcast_arrays(psi_true_deg, h_deg, pitch_deg, roll_deg)
        )
        curve, ok = self.curves(h, p, r)
        e = self._eval_on_curve(curve, np.arange(psi.size), psi)
        return np.where(ok, e, 0.0), ok

    # ------------------------------------------------------------------------------------------
    def correct_many(
        self, psi_meas_deg, h_deg, pitch_deg, roll_deg, mode: str = 'invert', oversample: int = 4
    ):
        """
        Correct many measured yaws at once.

        Parameters
        ----------
        psi_meas_deg : float or array_like
            Measured yaw psi [deg] (eq 21).
        h_deg : float or array_like
            Sun altitude [deg].
        pitch_deg, roll_deg : float or array_like
            Camera pitch alpha and roll beta [deg] (eq 21), broadcast together.
        mode : {"invert", "subtract"}, default "invert"
            Solve ``psi + e(psi) = psi_meas`` for psi, or the paper's ``psi_meas - e(psi_meas)``.
        oversample : int, default 4
            Sub-steps per yaw step of the root bracketing grid.

        Returns
        -------
        psi_deg : numpy.ndarray
            Corrected yaw [deg], shape (N,); 0 where there is no heading (status tells).
        status : numpy.ndarray
            int8 (N,) codes of :data:`STATUS_INT`.
        n_roots : numpy.ndarray
            Number of roots found per query (N,).

        Raises
        ------
        ErrorMapError
            Unknown ``mode``.

        References
        ----------
        .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), Sec. 3.4 (correcting the
           tilt error with the simulated errors).

        """
        return self._correct(psi_meas_deg, h_deg, pitch_deg, roll_deg, mode, oversample)[:3]

    def _correct(self, psi_meas_deg, h_deg, pitch_deg, roll_deg, mode, oversample=4):
        if mode not in ('invert', 'subtract'):
            raise ErrorMapError(f"correction mode must be 'invert' or 'subtract', got {mode!r}")
        meas, h, p, r = (
            np.atleast_1d(np.asarray(v, dtype=float))
            for v in np.broadcast_arrays(psi_meas_deg, h_deg, pitch_deg, roll_deg)
        )
        finite = np.isfinite(meas) & np.isfinite(h) & np.isfinite(p) & np.isfinite(r)
        meas = np.where(finite, meas, 0.0)
        h, p, r = (np.where(finite, v, 0.0) for v in (h, p, r))
        curve, ok = self.curves(h, p, r)
        ok &= finite
        status = np.where(
            ok, STATUS_INT[CorrectionStatus.OK], STATUS_INT[CorrectionStatus.OUT_OF_DOMAIN]
        )
        status = status.astype(np.int8)
        du = self.yaw_step / max(1, int(oversample))
        n_s = int(math.ceil(180.0 / du)) + 1
        u = np.linspace(-90.0, 90.0, n_s)  # offsets of the yaw search window, deg
        sub, psi, n_roots, cand = _invert_kernel(
            curve,
            ok,
            meas,
            self.yaw0,
            self.yaw_step,
            self.n_yaw,
            self.order == 3 and self.n_yaw >= 4,
            u,
            _MAX_ROOTS,
            mode == 'invert',
        )
        if mode == 'subtract':
            return np.where(ok, sub, 0.0), status, ok.astype(np.int64), cand
        status = np.where(ok & (n_roots == 0), STATUS_INT[CorrectionStatus.NO_SOLUTION], status)
        status = np.where(
            ok & (n_roots > 1), STATUS_INT[CorrectionStatus.MULTIPLE_SOLUTIONS], status
        )
        psi = np.where(ok & (n_roots > 0), psi, 0.0)
        return psi, status.astype(np.int8), n_roots, cand

    def correct(
        self,
        psi_meas_deg: float,
        sun_altitude_deg: float,
        pitch_deg: float,
        roll_deg: float,
        mode: str = 'invert',
    ) -> Correction:
        """
        Correct one measured yaw; out-of-domain input is a status, never an exception.

        Parameters
        ----------
        psi_meas_deg : float
            Measured yaw psi [deg] (eq 21).
        sun_altitude_deg : float
            Sun altitude [deg].
        pitch_deg, roll_deg : float
            Camera pitch alpha and roll beta [deg] (eq 21).
        mode : {"invert", "subtract"}, default "invert"
            Solve ``psi + e(psi) = psi_meas`` for psi, or the paper's ``psi_meas - e(psi_meas)``.

        Returns
        -------
        Correction
            Corrected psi [deg], the map's error there, all roots, and the status with its reason.

        Raises
        ------
        ErrorMapError
            Unknown ``mode``.

        References
        ----------
        .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), Sec. 3.4 (correcting the
           tilt error with the simulated errors).

        """
        vals = (psi_meas_deg, sun_altitude_deg, pitch_deg, roll_deg)
        if not all(
            isinstance(v, (int, float, np.floating, np.integer)) and math.isfinite(float(v))
            for v in vals
        ):
            return Correction(
                CorrectionStatus.OUT_OF_DOMAIN, mode=mode, reason=f'non-finite input {vals}'
            )
        psi, status, n_roots, cand = self._correct(*[float(v) for v in vals], mode=mode)
        st = _FROM_INT[int(status[0])]
        if st == CorrectionStatus.OUT_OF_DOMAIN:
            return Correction(st, mode=mode, reason=self._why_out(*[float(v) for v in vals[1:]]))
        if st == CorrectionStatus.NO_SOLUTION:
            return Correction(
                st, mode=mode, reason='no yaw in +-90 deg of the measurement predicts it'
            )
        cands = tuple(float(c) for c in np.sort(cand[0][np.isfinite(cand[0])]))
        psi0 = float(psi[0])
        err = float(wrap_180_deg(float(psi_meas_deg) - psi0))
        reason = (
            ''
            if st == CorrectionStatus.OK
            else f'{len(cands)} yaws predict this measurement; returned the one nearest the '
            'subtract estimate'
        )
        return Correction(st, psi0, err, cands, mode, reason)

    def correct_bearing(
        self,
        raw_bearing_deg: float,
        sun_azimuth_deg: float,
        sun_altitude_deg: float,
        pitch_deg: float,
        roll_deg: float,
        mode: str = 'invert',
    ):
        """
        Correct a true bearing of camera +y, as the ``tilt_corrector`` node and the replay do.

        Its psi against the sun (wrapped to (-180, 180]), :meth:`correct`, back to a bearing in [0,
        360).

        Parameters
        ----------
        raw_bearing_deg : float
            Measured bearing of camera +y [deg], clockwise from North.
        sun_azimuth_deg : float
            Sun azimuth [deg], clockwise from North.
        sun_altitude_deg : float
            Sun altitude [deg].
        pitch_deg, roll_deg : float
            Camera pitch alpha and roll beta [deg] (eq 21).
        mode : {"invert", "subtract"}, default "invert"
            Solve ``psi + e(psi) = psi_meas`` for psi, or the paper's ``psi_meas - e(psi_meas)``.

        Returns
        -------
        bearing_deg : float or None
            Corrected bearing [deg] in [0, 360); None when the correction is not ok.
        correction : Correction
            The correction in psi, with status and reason.

        Raises
        ------
        ErrorMapError
            Unknown ``mode``.

        """
        finite = math.isfinite(raw_bearing_deg) and math.isfinite(sun_azimuth_deg)
        psi_meas = float(wrap_180_deg(raw_bearing_deg - sun_azimuth_deg)) if finite else math.nan
        c = self.correct(psi_meas, sun_altitude_deg, pitch_deg, roll_deg, mode)
        return (float(psi_to_bearing_deg(c.psi_deg, sun_azimuth_deg)) if c.ok else None), c

    def correct_bearings(
        self,
        raw_bearing_deg,
        sun_azimuth_deg,
        sun_altitude_deg,
        pitch_deg,
        roll_deg,
        mode: str = 'invert',
    ):
        """
        Correct arrays of bearings as :meth:`correct_bearing` does, in one vectorised inversion.

        For the offline replay (one inversion instead of one per heading).

        Parameters
        ----------
        raw_bearing_deg : array_like
            Measured bearings of camera +y [deg], clockwise from North.
        sun_azimuth_deg : float or array_like
            Sun azimuth [deg], clockwise from North.
        sun_altitude_deg : float or array_like
            Sun altitude [deg].
        pitch_deg, roll_deg : float or array_like
            Camera pitch alpha and roll beta [deg] (eq 21), all broadcast together.
        mode : {"invert", "subtract"}, default "invert"
            Solve ``psi + e(psi) = psi_meas`` for psi, or the paper's ``psi_meas - e(psi_meas)``.

        Returns
        -------
        BearingCorrections
            ``(bearing_deg, ok, status)``: corrected bearings [deg] in [0, 360), shape (N,),
            finite everywhere (0.0 where ``ok`` is False); the bool validity mask; and the
            :class:`CorrectionStatus` value per heading, which says why a heading is not ok.

        Raises
        ------
        ErrorMapError
            Unknown ``mode``.

        """
        raw, az = (
            np.atleast_1d(np.asarray(v, dtype=float))
            for v in np.broadcast_arrays(raw_bearing_deg, sun_azimuth_deg)
        )
        finite = np.isfinite(raw) & np.isfinite(az)
        az = np.where(finite, az, 0.0)  # a non-finite input is out_of_domain, never NaN out
        psi_meas = np.where(finite, wrap_180_deg(np.where(finite, raw, 0.0) - az), np.nan)
        psi, status, _ = self.correct_many(psi_meas, sun_altitude_deg, pitch_deg, roll_deg, mode)
        ok = status == STATUS_INT[CorrectionStatus.OK]
        bearings = np.where(ok, psi_to_bearing_deg(np.where(ok, psi, 0.0), az), 0.0)
        return BearingCorrections(bearings, ok, [_FROM_INT[int(v)].value for v in status])

    def _why_out(self, h, p, r) -> str:
        a = self.alt
        if not (a[0] - 1e-9 <= h <= a[-1] + 1e-9):
            return f'sun altitude {h:g} deg outside the map ({a[0]:g}..{a[-1]:g})'
        if not (self.pitch[0] - 1e-9 <= p <= self.pitch[-1] + 1e-9):
            return f'pitch {p:g} deg outside the map ({self.pitch[0]:g}..{self.pitch[-1]:g})'
        if not (self.roll[0] - 1e-9 <= r <= self.roll[-1] + 1e-9):
            return f'roll {r:g} deg outside the map ({self.roll[0]:g}..{self.roll[-1]:g})'
        if not self.full_domain and abs(p) + abs(r) > self.tilt_limit_deg + 1e-9:
            return (
                f"|pitch| + |roll| = {abs(p) + abs(r):g} deg exceeds the map's limit "
                f'{self.tilt_limit_deg:g}'
            )
        return 'the map has no valid estimate at the nodes this point needs'
