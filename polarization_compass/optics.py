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
What the lens adds: the sun and its glare in the field, lens-flare ghosts, vignetting.

A scene declares these under ``optics`` (each key optional; nothing undeclared is constructed or
run, and each stage that runs is counted in :mod:`polarization_compass.instrumentation`)::

    optics:
      sun:        {disk_radiance: 2.0e5, glare_at_1deg: 30.0, glare_exponent: 2.0}
      flare:      {positions: [-0.37, -0.63, -0.83, -1.11], radius_px: 18, radiance: 0.6}
      vignetting: {law: cos4}  |  {k: [k1, k2, k3]}

All radiances are relative to the clear-sky zenith (the radiance models' unit). Light the lens adds
is unpolarized: where it adds ``G`` to a pixel of radiance ``I`` the DoP becomes ``DoP I / (I +
G)`` and the AoP is unchanged. A scene with a sensor ``exposure`` then saturates where the sum
exceeds the full well (the demosaic marks those pixels invalid), as the sun does in real frames.

Sun and glare
-------------
The solar disk (angular radius 0.2666 deg, the mean apparent semi-diameter) has radiance
``disk_radiance`` (the sun's luminance, ~1.6e9 cd/m^2, over a clear sky's ~8e3: about 2e5). Around
it the lens's veiling glare falls as a power of the angle gamma from the sun, ``glare_at_1deg * (1
deg / gamma) ** glare_exponent`` for gamma > the disk radius, the form of the Stiles-Holladay
disability-glare law (exponent 2; CIE 135/1-1999, Vos & van den Berg) that a lens's point-spread
wings also follow.

Lens-flare ghosts
-----------------
Internal reflections image the sun to ghosts on the line through the sun's image point ``s`` and
the optical centre ``c`` (the principal point): ghost k is centred on ``c + t_k (s - c)``, a disk
of ``radius_px`` with radiance ``radiance``. The default positions ``t`` are measured on the real
frame ``sunny.jpg`` (``../shared/data/real-sky/README.md``: sun at (762, 1750), centre (1076.3,
1000.9), ghosts at (1194, 726), (1272, 518), (1336, 373), (1427, 171): t = -0.37, -0.63, -0.83,
-1.11). Ghosts exist only while the sun projects into the image (its ray in front of a pinhole or
inside a fisheye's field).

Vignetting
----------
``law: cos4``: natural vignetting of a thin lens, irradiance ~ cos^4(theta) of the angle from the
optical axis (e.g. Kingslake, "Optical System Design", 1983). ``k: [k1, k2, k3]``: the radial
polynomial ``V = 1 + k1 r^2 + k2 r^4 + k3 r^6`` of the distance r from the principal point over the
half-diagonal (Goldman 2010, "Vignette and exposure calibration and compensation", IEEE TPAMI 32).
The radiance is multiplied by V; the DoP and AoP are unchanged.

"""

from __future__ import annotations

import math

import numpy as np

from .errors import CompassError
from .optics_kernels import (
    _flare_box_kernel,
    _OPTICS_BLOCK_KERNELS,
    _optics_kernel,
    Ghosts,
    LensParams,
)

__all__ = [
    'OpticsError',
    'Optics',
    'SUN_SEMIDIAMETER_DEG',
    'REAL_FRAME_GHOST_POSITIONS',
    'ghost_centres_px',
]

SUN_SEMIDIAMETER_DEG = 0.2666
#: Ghost positions t along sun -> centre measured on the real frame sunny.jpg (module docstring).
REAL_FRAME_GHOST_POSITIONS = (-0.37, -0.63, -0.83, -1.11)


class OpticsError(CompassError):
    """A scene's ``optics`` mapping that cannot be used; the message names the key."""


def _num(v, name, lo, hi):
    if isinstance(v, bool):
        raise OpticsError(f'optics.{name} must be a number, got {v!r}')
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise OpticsError(f'optics.{name} must be a number, got {v!r}') from None
    if not math.isfinite(f) or not (lo <= f <= hi):
        raise OpticsError(f'optics.{name} must be finite and in [{lo}, {hi}], got {v!r}')
    return f


def _keys(d, allowed, where):
    if not isinstance(d, dict):
        raise OpticsError(f'optics.{where} must be a mapping, got {type(d).__name__}')
    unknown = set(d) - set(allowed)
    if unknown:
        raise OpticsError(
            f'unknown key(s) {sorted(unknown)} in optics.{where}; allowed: {sorted(allowed)}'
        )


def _block_axes(x_px, y_px):
    """
    Return the (columns, rows) whose product the pixel coordinates are, else None.

    float32, when ``x_px[r, c] = columns[c]`` and ``y_px[r, c] = rows[r]``, both increasing.
    """
    if x_px.ndim != 2 or y_px.shape != x_px.shape or x_px.size == 0:
        return None
    xc = np.ascontiguousarray(x_px[0], np.float32)
    yr = np.ascontiguousarray(y_px[:, 0], np.float32)
    if (np.diff(xc) <= 0).any() or (np.diff(yr) <= 0).any():
        return None
    if not (
        np.array_equal(x_px, np.broadcast_to(x_px[0], x_px.shape))
        and np.array_equal(y_px, np.broadcast_to(y_px[:, :1], y_px.shape))
    ):
        return None
    return xc, yr


def ghost_centres_px(sun_px, centre_px, positions):
    """
    Return the ghost centres (k, 2) px on the line through the sun's image and the centre.

    Ghost k is centred on ``c + t_k (s - c)`` (module docstring, "Lens-flare ghosts").

    Parameters
    ----------
    sun_px : array_like, shape (2,)
        The sun's image point s (x, y) [px, 1-based, eq 20 convention].
    centre_px : array_like, shape (2,)
        The optical centre c (principal point) (x, y) [px, 1-based].
    positions : array_like, shape (k,)
        Ghost positions t_k along c -> s (dimensionless; negative: beyond the centre), e.g.
        :data:`REAL_FRAME_GHOST_POSITIONS`.

    Returns
    -------
    numpy.ndarray, shape (k, 2), float64
        Ghost centres (x, y) [px].

    """
    s = np.asarray(sun_px, dtype=float)
    c = np.asarray(centre_px, dtype=float)
    t = np.asarray(positions, dtype=float).reshape(-1, 1)
    return c + t * (s - c)


class Optics:
    """
    The declared lens effects of a scene.

    Applied in the order vignetting (to the sky), sun, flare (module docstring).

    Parameters
    ----------
    cfg : dict
        A scene's ``optics`` mapping with optional ``sun``, ``flare`` and ``vignetting`` mappings;
        a missing or None stage is not built.
    camera : CameraModel
        The scene's :class:`~polarization_compass.camera.CameraModel` (projection, principal
        point, image size).

    Raises
    ------
    OpticsError
        ``cfg`` or a stage is not a mapping, has an unknown key, a value is not a number or out of
        its range, the vignetting gives neither or both of ``law`` and ``k``, or its polynomial is
        not positive inside the image.

    """

    def __init__(self, cfg: dict, camera):
        _keys(cfg, {'sun', 'flare', 'vignetting'}, '')
        self.camera = camera
        self.sun = self.flare = self.vignetting = None
        if cfg.get('sun') is not None:
            s = cfg['sun']
            _keys(s, {'disk_radiance', 'glare_at_1deg', 'glare_exponent'}, 'sun')
            self.sun = {
                'disk_radiance': _num(
                    s.get('disk_radiance', 2.0e5), 'sun.disk_radiance', 0.0, 1e9
                ),
                'glare_at_1deg': _num(s.get('glare_at_1deg', 30.0), 'sun.glare_at_1deg', 0.0, 1e9),
                'glare_exponent': _num(
                    s.get('glare_exponent', 2.0), 'sun.glare_exponent', 0.5, 6.0
                ),
            }
        if cfg.get('flare') is not None:
            f = cfg['flare']
            _keys(f, {'positions', 'radius_px', 'radiance'}, 'flare')
            pos = f.get('positions', list(REAL_FRAME_GHOST_POSITIONS))
            if not isinstance(pos, (list, tuple)) or not 1 <= len(pos) <= 32:
                raise OpticsError(
                    'optics.flare.positions must be a list of 1-32 numbers (t along sun -> centre)'
                )
            self.flare = {
                'positions': [_num(t, 'flare.positions', -10.0, 10.0) for t in pos],
                'radius_px': _num(f.get('radius_px', 18.0), 'flare.radius_px', 0.5, 5000.0),
                'radiance': _num(f.get('radiance', 0.6), 'flare.radiance', 0.0, 1e9),
            }
        if cfg.get('vignetting') is not None:
            v = cfg['vignetting']
            _keys(v, {'law', 'k'}, 'vignetting')
            if ('law' in v) == ('k' in v):
                raise OpticsError('optics.vignetting needs either law: cos4 or k: [k1, k2, k3]')
            if 'law' in v:
                if v['law'] != 'cos4':
                    raise OpticsError(f"optics.vignetting.law must be 'cos4', got {v['law']!r}")
                self.vignetting = {'law': 'cos4'}
            else:
                k = v['k'] if isinstance(v['k'], (list, tuple)) else [v['k']]
                if not 1 <= len(k) <= 3:
                    raise OpticsError('optics.vignetting.k must be 1-3 numbers [k1, k2, k3]')
                ks = [_num(x, 'vignetting.k', -10.0, 10.0) for x in k]
                r = np.linspace(0.0, 1.0, 101)
                if (1.0 + sum(c * r ** (2 * (j + 1)) for j, c in enumerate(ks))).min() <= 0.0:
                    raise OpticsError(
                        'optics.vignetting.k gives a non-positive falloff inside the image'
                    )
                self.vignetting = {'k': ks}

    @property
    def stages(self) -> list[str]:
        """Return the names of the declared stages in the order they are applied."""
        return [n for n in ('vignetting', 'sun', 'flare') if getattr(self, n) is not None]

    def params(self) -> dict:
        """
        Return the parameters of each declared stage, defaults filled in.

        Returns
        -------
        dict
            Stage name -> a copy of that stage's parameter mapping.

        """
        return {n: dict(getattr(self, n)) for n in self.stages}

    def sun_px(self, sun_cam):
        """
        Return the sun's image point (x, y) px, or None outside the lens' field.

        The sun projects when its ray is in front of a pinhole camera (z > 1e-6) or inside a
        fisheye's ``max_field_angle_deg``.

        Parameters
        ----------
        sun_cam : array_like, shape (3,)
            Unit sun vector in the camera frame.

        Returns
        -------
        tuple of float or None
            (x, y) [px, 1-based, eq 20 convention], possibly outside the image bounds; None when
            the sun does not project into the lens' field.

        """
        s = np.asarray(sun_cam, dtype=float).reshape(3, 1)
        cam = self.camera
        if cam.model == 'pinhole':
            if s[2, 0] <= 1e-6:
                return None
        elif math.degrees(math.acos(min(1.0, max(-1.0, s[2, 0])))) > cam.max_field_angle_deg:
            return None
        x, y = cam.pixels_from_rays(s)
        return float(x[0]), float(y[0])

    def apply(self, sun_cam, rays_cam, x_px, y_px, aop, dop, intensity, instr) -> None:
        """
        Apply the declared lens effects to the flat arrays in place.

        Vignetting multiplies the radiance; the sun, its glare and the ghosts add unpolarized light
        G, so the DoP becomes ``DoP I / (I + G)`` and the AoP is unchanged (module docstring).
        Each declared stage is counted. A block of pixels (the product of its columns and rows:
        full, region, stride, grid) runs one fused vignetting + sun pass and then the ghosts over
        their bounding boxes only; scattered pixels run one fused pass with flat coordinates.

        Parameters
        ----------
        sun_cam : array_like, shape (3,)
            Sun direction in the camera frame (normalised here).
        rays_cam : array_like, shape (3, N)
            Unit viewing rays of the pixels in the camera frame (converted to contiguous float32).
        x_px, y_px : numpy.ndarray
            The pixels' 1-based column and row coordinates [px] (eq 20), in the selection's shape.
        aop : numpy.ndarray, shape (N,), float32
            Angle of polarization [rad]; not changed (unpolarized light keeps the AoP).
        dop : numpy.ndarray, shape (N,), float32
            Degree of polarization [0, 1]; modified in place.
        intensity : numpy.ndarray, shape (N,), float32
            Writable radiance relative to the clear zenith; modified in place.
        instr : module or object
            Instrumentation with a ``count(name)`` function, normally
            :mod:`polarization_compass.instrumentation`.

        References
        ----------
        .. [1] CIE 135/1-1999 (Stiles-Holladay disability glare; Vos and van den Berg).
        .. [2] D. B. Goldman, "Vignette and exposure calibration and compensation", IEEE TPAMI 32,
           2010.

        """
        lens, square, ghosts = self.frame_params(sun_cam, instr)
        rays = np.ascontiguousarray(rays_cam, dtype=np.float32)
        axes = self.block_axes(x_px, y_px)
        if axes is not None:
            xc, yr = axes
            if lens.vig_mode or self.sun is not None:
                _OPTICS_BLOCK_KERNELS[square](rays, xc, yr, lens, dop, intensity)
            self.add_ghosts(ghosts, xc, yr, dop, intensity)
            return
        x = np.ascontiguousarray(np.asarray(x_px, np.float32).reshape(-1))
        y = np.ascontiguousarray(np.asarray(y_px, np.float32).reshape(-1))
        _optics_kernel(rays, x, y, lens, square, ghosts, dop, intensity)

    def frame_params(self, sun_cam, instr):
        """
        Count the declared stages and return the frame's lens parameters and ghosts.

        Parameters
        ----------
        sun_cam : array_like, shape (3,)
            Sun direction in the camera frame (normalised here).
        instr : module or object
            Instrumentation with a ``count(name)`` function; each declared stage is counted once.

        Returns
        -------
        lens : LensParams
            The lens parameters of :func:`lens_over` and :func:`lens_light`.
        square : bool
            Whether the glare exponent is 2 (the kernels' fast glare law).
        ghosts : Ghosts
            The ghost centres (empty without flare or when the sun does not project), their
            squared radius and radiance.

        """
        f32 = np.float32
        vig_mode, ks = 0, (0.0, 0.0, 0.0)
        if self.vignetting is not None:
            instr.count('optics.vignetting')
            if 'law' in self.vignetting:
                vig_mode = 1
            else:
                vig_mode = 2
                ks = tuple(self.vignetting['k']) + (0.0,) * (3 - len(self.vignetting['k']))
        s = np.asarray(sun_cam, dtype=float)
        s = s / np.linalg.norm(s)
        p = self.sun or {'disk_radiance': 0.0, 'glare_at_1deg': 0.0, 'glare_exponent': 2.0}
        if self.sun is not None:
            instr.count('optics.sun')
        square = p['glare_exponent'] == 2.0
        g1 = p['glare_at_1deg'] * (math.radians(1.0) ** 2 if square else 1.0)
        gx = gy = np.empty(0, np.float32)
        r2 = grad = 0.0
        if self.flare is not None:
            instr.count('optics.flare')
            sp = self.sun_px(sun_cam)
            if sp is not None:
                g = ghost_centres_px(
                    sp, (self.camera.cx_px, self.camera.cy_px), self.flare['positions']
                )
                gx, gy = (
                    np.ascontiguousarray(g[:, 0], np.float32),
                    np.ascontiguousarray(g[:, 1], np.float32),
                )
                r2, grad = self.flare['radius_px'] ** 2, self.flare['radiance']
        cam = self.camera
        lens = LensParams(
            vig_mode,
            f32(cam.cx_px),
            f32(cam.cy_px),
            f32(4.0 / (cam.width_px**2 + cam.height_px**2)),
            f32(ks[0]),
            f32(ks[1]),
            f32(ks[2]),
            self.sun is not None,
            f32(s[0]),
            f32(s[1]),
            f32(s[2]),
            f32(math.radians(SUN_SEMIDIAMETER_DEG) ** 2),
            f32(p['disk_radiance']),
            f32(g1),
            f32(p['glare_exponent']),
        )
        return lens, square, Ghosts(gx, gy, f32(r2), f32(grad))

    def add_ghosts(self, ghosts, xc, yr, dop, intensity) -> None:
        """
        Add the lens-flare ghosts to a block of pixels, visiting only their bounding boxes.

        Parameters
        ----------
        ghosts : Ghosts
            The frame's ghosts, from :meth:`frame_params`.
        xc, yr : numpy.ndarray, float32
            The block's columns and rows [px, 1-based] (:meth:`block_axes`).
        dop : numpy.ndarray, shape (N,), float32
            Degree of polarization, row-major over the block; scaled in place by I / (I + grad).
        intensity : numpy.ndarray, shape (N,), float32
            Radiance; the ghosts' radiance is added in place.

        """
        gx, gy = ghosts.gx, ghosts.gy
        if not gx.size:
            return
        rad = math.sqrt(ghosts.r2)
        boxes = np.array(
            [
                [
                    np.searchsorted(yr, gy[k] - rad, 'left'),
                    np.searchsorted(yr, gy[k] + rad, 'right'),
                    np.searchsorted(xc, gx[k] - rad, 'left'),
                    np.searchsorted(xc, gx[k] + rad, 'right'),
                ]
                for k in range(gx.size)
            ],
            dtype=np.int64,
        )
        _flare_box_kernel(boxes, xc, yr, ghosts, dop, intensity)

    def block_axes(self, x_px, y_px):
        """
        Return the (columns, rows) whose product the pixel coordinates are, else None.

        Computed once per coordinate array (:func:`_block_axes`).

        Parameters
        ----------
        x_px, y_px : numpy.ndarray
            The pixels' 1-based column and row coordinates [px], in the selection's shape.

        Returns
        -------
        tuple of numpy.ndarray or None
            (columns, rows) float32, increasing, or None when the pixels are not such a block.

        """
        key = (id(x_px), id(y_px), np.shape(x_px))
        if getattr(self, '_axes_key', None) != key:
            self._axes_val = _block_axes(np.asarray(x_px), np.asarray(y_px))
            self._axes_key = key
            self._axes_ref = (x_px, y_px)  # keep them alive so that their ids stay theirs
        return self._axes_val
