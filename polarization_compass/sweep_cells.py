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
Per-process evaluation of error-map sweep cells, shared by every sweep backend.

:class:`CellEvaluator` holds one estimator per method and one renderer per distinct pixel
selection; the in-process driver (:mod:`polarization_compass.sweep`) and the Dask workers
(:mod:`polarization_compass.sweep_dask`) both build it from a
:class:`~polarization_compass.sweep_spec.SweepSpec`, so the two cannot differ in what a cell
computes.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

from .conventions import CameraAttitude, fold_axial_deg
from .errormap import STATUS_CODES, STATUS_ESTIMATOR_ERROR, STATUS_NOT_COMPUTED, STATUS_OTHER

__all__ = ['CellEvaluator']


# --------------------------------------------------------------------------------------------
# Workers
# --------------------------------------------------------------------------------------------
class CellEvaluator:
    """
    Per-process state: one estimator per method and one renderer per distinct pixel selection.

    A noise-free cell is rendered with :meth:`Renderer.render_sky` (the sky arrays only: no Frame,
    no metadata) from attitude matrices computed for all yaws of a chunk at once; methods that read
    the same pixels share the render. (One render of the union of the selections was tried: it
    saves ~40 us per cell but is not bit for bit the same as each selection's own render when numba
    splits the loop over threads differently.) A scene with sensor effects renders full frames (the
    noise of a cell comes from its seed). Every method skips its uncertainty (``estimate(obs,
    sigma=False)``): a map stores psi's error and the status only.
    """

    def __init__(self, spec):  # a sweep_spec.SweepSpec
        from .estimators import make_estimator
        from .render import Renderer

        self.spec = spec
        self.errors: list[str] = []
        if spec.array:  # a photodiode array: readings from the sun in the body frame, no pixels
            from .photodiode.heading import make_array_estimator
            from .photodiode.simulate import ArraySensor
            from .sky_models import make_sky_model

            self.array = ArraySensor.from_config(spec.scene.photodiode_array)
            self.array_dop_max = float(make_sky_model(spec.scene.sky).params().get('dop_max', 1.0))
            self.estimators = [
                make_array_estimator(m, self.array.geometry, **spec.knobs[m]) for m in spec.methods
            ]
            self.groups, self.noisy = [], self.array.noise_rel > 0
            return
        self.estimators = [make_estimator(m, **spec.knobs[m]) for m in spec.methods]
        camera = spec.scene.camera
        self.groups: list[tuple[object, list[int]]] = []  # (renderer, method indices)
        by_sel: dict = {}
        for i, est in enumerate(self.estimators):
            sel = est.pixels_needed(camera)
            if sel not in by_sel:
                by_sel[sel] = len(self.groups)
                self.groups.append((Renderer(spec.scene, pixels=sel), []))
            self.groups[by_sel[sel]][1].append(i)
        self.noisy = bool(spec.scene.effects)

    def sampling(self) -> dict:
        """
        Describe what each method reads, for the map's meta.

        Returns
        -------
        dict
            Per method: its knobs and either the pixel selection (description and count) or, for a
            photodiode array, the number of units.

        """
        if self.spec.array:
            return {
                m: {'knobs': self.spec.knobs[m], 'units': self.array.geometry.n_units}
                for m in self.spec.methods
            }
        out = {}
        for renderer, idx in self.groups:
            for i in idx:
                out[self.spec.methods[i]] = {
                    'knobs': self.spec.knobs[self.spec.methods[i]],
                    'pixels': renderer.selection.describe(),
                    'pixel_count': int(renderer.pixels.count),
                }
        return out

    def _seed(self, ia, iy, ip, ir) -> int:
        h = hashlib.blake2b(
            f'{self.spec.scene.seed}:{ia}:{iy}:{ip}:{ir}'.encode(), digest_size=8
        ).digest()
        return int.from_bytes(h, 'little') & 0x7FFFFFFF

    def _frames(self, sun_cam, zenith_cam):
        """
        Return the per-selection pixels and AoP/DoP frames of one noise-free cell.

        (pixels, method indices, aop, dop, valid, intensity) per pixel selection for one noise-free
        cell.
        """
        out = []
        for renderer, idx in self.groups:
            aop, dop, valid, inten = renderer.render_sky(sun_cam, zenith_cam)
            shape = renderer.pixels.shape
            out.append(
                (
                    renderer.pixels,
                    idx,
                    aop.reshape(shape),
                    dop.reshape(shape),
                    valid.reshape(shape),
                    None if inten is None else inten.reshape(shape),
                )
            )
        return out

    def _noisy_frames(self, att, sun, seed):
        """
        Return the frames of one cell for a scene with sensor effects.

        The same for a scene with sensor effects: full frames, noise from the cell's seed (the
        pixels are the frame's demosaiced ones).
        """
        out = []
        for renderer, idx in self.groups:
            f = renderer.render(attitude=att, sun=sun, seed=seed)
            out.append((f.pixels, idx, f.aop_rad, f.dop, f.valid, f.intensity))
        return out

    def chunk(self, ia: int, ip: int):
        """
        Compute one chunk: every method, yaw and roll at one sun altitude and one pitch.

        Parameters
        ----------
        ia : int
            Index into the spec's sun altitudes [deg].
        ip : int
            Index into the spec's pitches [deg]; rolls outside the tilt domain stay not computed.

        Returns
        -------
        err : numpy.ndarray
            Heading error [deg], axial (folded to (-90, 90]), shape (methods, yaws, rolls).
        status : numpy.ndarray
            int8 status codes of :data:`polarization_compass.errormap.STATUS_CODES`, same shape.

        References
        ----------
        Attitudes follow the seed paper's eq 21 (yaw psi, pitch alpha, roll beta); the error is the
        paper's section 3 tilt error.

        """
        from .conventions import enu_direction, R_enu_cam_from_attitude
        from .estimators.base import Observation
        from .render import SunDirection

        spec = self.spec
        camera = spec.scene.camera
        M, Y, R = len(spec.methods), spec.yaw_deg.size, spec.roll_deg.size
        err = np.zeros((M, Y, R), dtype=float)
        status = np.full((M, Y, R), STATUS_NOT_COMPUTED, dtype=np.int8)
        rolls = np.nonzero(spec.tilt_mask()[ip])[0].tolist()
        h = float(spec.sun_altitude_deg[ia])
        pitch = float(spec.pitch_deg[ip])
        sun = SunDirection(0.0, h)
        sun_enu = enu_direction(0.0, h)
        geometry = {}
        for ir in rolls:
            # bearing == psi (sun at azimuth 0): the rotations R of every yaw at once, and the
            # camera-frame sun R^T s and zenith R^T (0, 0, 1) that Renderer.render computes
            Rs = R_enu_cam_from_attitude(spec.yaw_deg, pitch, float(spec.roll_deg[ir]))
            geometry[ir] = (np.matmul(np.swapaxes(Rs, 1, 2), sun_enu), Rs[:, 2, :].copy())
        if spec.array:
            self._array_chunk(ia, ip, rolls, geometry, err, status)
            return err, status
        for iy, psi in enumerate(spec.yaw_deg.tolist()):
            for ir in rolls:
                roll = float(spec.roll_deg[ir])
                if self.noisy:
                    frames = self._noisy_frames(
                        CameraAttitude(psi, pitch, roll), sun, self._seed(ia, iy, ip, ir)
                    )
                else:
                    frames = self._frames(geometry[ir][0][iy], geometry[ir][1][iy])
                for px, idx, aop, dop, valid, inten in frames:
                    obs = Observation(
                        aop,
                        dop,
                        valid,
                        px.rays_cam,
                        px.x_px,
                        px.y_px,
                        camera,
                        0.0,
                        h,
                        inten,
                        pitch,
                        roll,
                        None,
                    )
                    for i in idx:
                        err[i, iy, ir], status[i, iy, ir] = self._one(i, obs, psi)
        return err, status

    def _array_chunk(self, ia, ip, rolls, geometry, err, status) -> None:
        """
        Compute the photodiode-array cells of one chunk.

        The array's cells of one chunk: readings for the camera-frame sun of each cell (the array
        is mounted like the default camera), the per-unit fit, then each method (sun at azimuth 0:
        bearing == psi).
        """
        from .conventions import R_BODY_CAM_DEFAULT
        from .photodiode.stokes import fit_stokes

        spec = self.spec
        h, pitch = float(spec.sun_altitude_deg[ia]), float(spec.pitch_deg[ip])
        for iy, psi in enumerate(spec.yaw_deg.tolist()):
            for ir in rolls:
                rng = np.random.default_rng(self._seed(ia, iy, ip, ir)) if self.noisy else None
                x = self.array.read(
                    R_BODY_CAM_DEFAULT @ geometry[ir][0][iy], self.array_dop_max, rng
                )
                st = fit_stokes(x[None], self.array.geometry)
                args = (
                    st.aop_rad[0],
                    st.dop[0],
                    st.s0[0],
                    st.valid[0],
                    0.0,
                    h,
                    pitch,
                    float(spec.roll_deg[ir]),
                )
                for i in range(len(spec.methods)):
                    err[i, iy, ir], status[i, iy, ir] = self._one(i, args, psi)

    def _one(self, i: int, obs, psi_true: float):
        try:
            est = self.estimators[i]
            res = est.estimate(*obs) if self.spec.array else est.estimate(obs, sigma=False)
        # one bad cell must not kill an hour-long sweep; reported
        except Exception as exc:  # noqa: BLE001
            if len(self.errors) < 5:
                self.errors.append(f'{self.spec.methods[i]}: {type(exc).__name__}: {exc}')
            return 0.0, STATUS_ESTIMATOR_ERROR
        code = STATUS_CODES.get(getattr(res.status, 'value', str(res.status)), STATUS_OTHER)
        if code in (0, 1):
            if res.psi_deg is None or not math.isfinite(res.psi_deg):
                return 0.0, STATUS_ESTIMATOR_ERROR
            return fold_axial_deg(float(res.psi_deg) - psi_true), code
        return 0.0, code


# --------------------------------------------------------------------------------------------
# Driver
# --------------------------------------------------------------------------------------------
#: What ``out`` may name: today's ``.npz``, one NetCDF 3 file, or the Zarr store itself.
