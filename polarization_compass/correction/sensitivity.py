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
How a tilt correction responds to the attitude: derivatives of the map and the attitude's sigma.

:class:`_AttitudeSensitivity` holds the methods of :class:`.corrector.TiltCorrector` that
differentiate the interpolated error map (:meth:`~_AttitudeSensitivity.error_gradient`), the
corrected yaw with respect to pitch and roll (:meth:`~_AttitudeSensitivity.heading_sensitivity`)
and propagate the attitude's uncertainty (:meth:`~_AttitudeSensitivity.attitude_sigma_deg`); the
corrector inherits them and supplies the map, its axes and the interpolation.
"""

from __future__ import annotations

import numpy as np

from .kernels import _accumulate_curves
from .weights import _axis_weights
from ..errormap import ErrorMapError

#: Floor of |1 + de/dpsi| in :meth:`TiltCorrector.heading_sensitivity` (a slope that small means
#: roots about to coalesce: the inversion's status already says ``multiple_solutions``).
_MIN_SLOPE = 0.05


class _AttitudeSensitivity:
    """The attitude derivatives of :class:`.corrector.TiltCorrector`, which inherits them."""

    def _tilt_grad_curves(self, h, p, r, order):
        """d(curve)/d(pitch) and d(curve)/d(roll) over the yaw nodes (N, Y) at ``order``."""
        (ia, wa), (ip, wp), (ir, wr), inside = self._tilt_weights(h, p, r, order)
        _, dwp, _ = _axis_weights(self.pitch, p, order, deriv=True)
        _, dwr, _ = _axis_weights(self.roll, r, order, deriv=True)
        ok = inside.copy()
        c = np.ascontiguousarray
        gp = _accumulate_curves(self.E, self.V, c(ia), c(wa), c(ip), c(dwp), c(ir), c(wr), ok)
        gr = _accumulate_curves(self.E, self.V, c(ia), c(wa), c(ip), c(wp), c(ir), c(dwr), ok)
        return gp, gr, ok, inside

    def error_gradient(self, psi_deg, h_deg, pitch_deg, roll_deg):
        """
        Differentiate the interpolated error map at given yaws, as :meth:`predicted_error` reads.

        The derivatives of the interpolant itself (Keys' cubic convolution is C1; multilinear cells
        have one-sided derivatives at nodes), with the same cubic/multilinear choice per point as
        :meth:`curves`.

        Parameters
        ----------
        psi_deg : float or array_like
            Yaw psi [deg] (eq 21).
        h_deg : float or array_like
            Sun altitude [deg].
        pitch_deg, roll_deg : float or array_like
            Camera pitch alpha and roll beta [deg] (eq 21), broadcast together.

        Returns
        -------
        de_dpsi, de_dpitch, de_droll : numpy.ndarray
            Partial derivatives of the error ``e(psi, h, pitch, roll)`` [deg/deg], shape (N,); 0
            where not ok.
        ok : numpy.ndarray
            bool (N,), as :meth:`predicted_error`.

        References
        ----------
        .. [1] R. Keys, "Cubic convolution interpolation for digital image processing", IEEE
           Transactions on Acoustics, Speech, and Signal Processing 29(6): 1153-1160, 1981.

        """
        psi, h, p, r = (
            np.atleast_1d(np.asarray(v, dtype=float))
            for v in np.broadcast_arrays(psi_deg, h_deg, pitch_deg, roll_deg)
        )
        curve, ok = self.curves(h, p, r)
        gp, gr, _, inside = self._tilt_grad_curves(h, p, r, self.order)
        if self.order == 3:
            _, ok3, _ = self._curves_order(h, p, r, 3)
            bad = ~ok3 & inside
            if bad.any():  # the points :meth:`curves` read multilinearly
                gp1, gr1, _, _ = self._tilt_grad_curves(h[bad], p[bad], r[bad], 1)
                gp[bad], gr[bad] = gp1, gr1
        rows = np.arange(psi.size)
        out = (
            self._eval_on_curve(curve, rows, psi, deriv=True),
            self._eval_on_curve(gp, rows, psi),
            self._eval_on_curve(gr, rows, psi),
        )
        return tuple(np.where(ok, v, 0.0) for v in out) + (ok,)

    def heading_sensitivity(self, psi_deg, h_deg, pitch_deg, roll_deg, mode: str = 'invert'):
        """
        Return how the corrected yaw moves with the pitch and roll the correction is given.

        ``invert`` solves ``psi + e(psi, pitch, roll) = psi_meas``, so by the implicit function
        theorem ``d psi / d pitch = -(de/dpitch) / (1 + de/dpsi)`` at the corrected ``psi`` (the
        denominator's magnitude floored at 0.05: where it vanishes the inversion has coalescing
        roots and the status is already ``multiple_solutions``); ``subtract`` computes ``psi =
        psi_meas - e(psi_meas, pitch, roll)``, so ``-de/dpitch`` at the measured yaw. The
        attitude's share of the corrected heading's variance is then ``J Sigma_att J^T``.

        Parameters
        ----------
        psi_deg : float or array_like
            The corrected yaw psi [deg] for ``invert``, the measured one for ``subtract``.
        h_deg : float or array_like
            Sun altitude [deg].
        pitch_deg, roll_deg : float or array_like
            Camera pitch alpha and roll beta [deg] (eq 21) the correction used, broadcast together.
        mode : {"invert", "subtract"}, default "invert"
            The correction's mode.

        Returns
        -------
        dpsi_dpitch, dpsi_droll : numpy.ndarray
            [deg/deg], shape (N,); 0 where not ok.
        ok : numpy.ndarray
            bool (N,), as :meth:`predicted_error`.

        Raises
        ------
        ErrorMapError
            Unknown ``mode``.

        """
        if mode not in ('invert', 'subtract'):
            raise ErrorMapError(f"correction mode must be 'invert' or 'subtract', got {mode!r}")
        e_psi, e_p, e_r, ok = self.error_gradient(psi_deg, h_deg, pitch_deg, roll_deg)
        if mode == 'subtract':
            return -e_p, -e_r, ok
        den = 1.0 + e_psi
        den = np.where(np.abs(den) < _MIN_SLOPE, np.copysign(_MIN_SLOPE, den), den)
        return -e_p / den, -e_r / den, ok

    def attitude_sigma_deg(
        self,
        psi_deg,
        h_deg,
        pitch_deg,
        roll_deg,
        pitch_sigma_deg,
        roll_sigma_deg,
        mode: str = 'invert',
    ):
        """
        Propagate the attitude's uncertainty into the corrected yaw: ``sqrt(J Sigma_att J^T)``.

        ``J`` is :meth:`heading_sensitivity`; ``Sigma_att = diag(pitch_sigma^2, roll_sigma^2)``
        (pitch and roll errors taken as uncorrelated).

        Parameters
        ----------
        psi_deg, h_deg, pitch_deg, roll_deg : float or array_like
            As :meth:`heading_sensitivity` [deg].
        pitch_sigma_deg, roll_sigma_deg : float or array_like
            1-sigma uncertainty of the pitch and roll the correction was given [deg].
        mode : {"invert", "subtract"}, default "invert"
            The correction's mode.

        Returns
        -------
        sigma_deg : numpy.ndarray
            1-sigma of the corrected yaw due to the attitude [deg], shape (N,); 0 where not ok.
        ok : numpy.ndarray
            bool (N,).

        """
        jp, jr, ok = self.heading_sensitivity(psi_deg, h_deg, pitch_deg, roll_deg, mode)
        sp, sr = np.broadcast_arrays(
            np.asarray(pitch_sigma_deg, dtype=float), np.asarray(roll_sigma_deg, dtype=float)
        )
        return np.where(ok, np.hypot(jp * sp, jr * sr), 0.0), ok
