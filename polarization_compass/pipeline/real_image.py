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
A real image's observation: the whole image, as camera-frame Stokes, masked to the usable sky.

:func:`real_observation` turns a real input (raw mosaic or Stokes planes, with its camera file)
into the :class:`~polarization_compass.estimators.Observation` every method reads, and the data
mask the polarizer check and the diagnostic figure use.
"""

from __future__ import annotations

from ..errors import CompassError

__all__ = ['real_observation']


def real_observation(
    inp,
    cam_file,
    sun_az,
    sun_alt,
    mask=None,
    demosaic='superpixel',
    pitch=None,
    roll=None,
    prior=None,
    ifov_k=None,
):
    """
    Build the observation of a whole real image and its data mask.

    Stokes planes are turned into camera-frame Stokes (S2 changes sign when the 45 deg polarizer
    points towards +x-y, see :mod:`polarization_compass.demosaic`); a raw mosaic is demosaiced with
    the camera file's layout. Invalid: outside the lens, saturated (+ glare), masked, and for a raw
    mosaic the IFOV check's rejections.

    Parameters
    ----------
    inp : PolarizationInput
        The image (:func:`polarization_compass.real_input.load_polarization_input`).
    cam_file : CameraFile
        The camera and its polarizer.
    sun_az, sun_alt : float
        Sun azimuth [deg, clockwise from North] and altitude [deg].
    mask : numpy.ndarray of bool, optional
        True = sky; the input's size or the sensor's.
    demosaic : {"superpixel", "bilinear"}, default "superpixel"
        Demosaic of a raw mosaic.
    pitch, roll : float, optional
        Known camera pitch and roll [deg].
    prior : float, optional
        Prior bearing of camera +y [deg].
    ifov_k : float, optional
        IFOV check threshold [noise sigmas] (default ``demosaic.IFOV_K_DEFAULT``; 0 = off).

    Returns
    -------
    tuple
        (Observation of the whole image, data mask as bool array of the planes' shape).

    Raises
    ------
    CompassError
        The input, the camera file and the mask do not agree in size.

    """
    from ..demosaic import aop_dop_from_stokes
    from ..estimators import Observation
    from ..polarizer_files import plane_rays

    cam = cam_file.camera
    s0, s1, s2, saturated = _camera_stokes(inp, cam_file, demosaic, ifov_k)
    xg, yg, rays, has_ray = plane_rays(cam, s0.shape)
    aop, dop, valid = aop_dop_from_stokes(s0, s1, s2)
    keep = _sky_mask(s0, has_ray, saturated, mask, xg, yg, cam.shape)
    valid = valid & keep
    obs = Observation(aop, dop, valid, rays, xg, yg, cam, sun_az, sun_alt, s0, pitch, roll, prior)
    return obs, keep


def _camera_stokes(inp, cam_file, demosaic, ifov_k):
    """Camera-frame (S0, S1, S2) of a real input and, for a raw mosaic, its saturated blocks."""
    from ..demosaic import IFOV_K_DEFAULT, stokes_from_mosaic

    H, W = cam_file.camera.shape
    if inp.kind == 'stokes':
        s0, s1, s2 = inp.stokes
        if cam_file.pol45_toward == '+x-y':
            s2 = -s2
        return s0, s1, s2, None
    if inp.mosaic.shape != (H, W):
        raise CompassError(
            f'the mosaic is {inp.mosaic.shape[1]} x {inp.mosaic.shape[0]} but the camera file '
            'says '
            f'{W} x {H}'
        )
    s0, s1, s2 = stokes_from_mosaic(
        inp.mosaic,
        cam_file.layout,
        cam_file.pol45_toward,
        demosaic,
        inp.saturation_level,
        IFOV_K_DEFAULT if ifov_k is None else ifov_k,
    )
    from ..polarizer_check import saturated_blocks

    return s0, s1, s2, saturated_blocks(inp.mosaic, inp.saturation_level, s0.shape)


def _sky_mask(s0, has_ray, saturated, mask, xg, yg, sensor_shape):
    """Pixels to use: in the lens, not glare (saturated samples grown), not masked."""
    import numpy as np

    from ..skyfit import data_mask

    H, W = sensor_shape
    shp = s0.shape
    if saturated is None:
        keep = data_mask(s0, has_ray)
    else:  # saturated raw samples: grow those into the glare mask
        keep = data_mask(np.where(saturated, np.float32(np.inf), s0), has_ray, float('inf'))
    if mask is not None:
        if mask.shape == shp:
            keep &= mask
        elif mask.shape == (H, W):
            keep &= mask[
                np.clip(np.rint(yg).astype(int) - 1, 0, H - 1),
                np.clip(np.rint(xg).astype(int) - 1, 0, W - 1),
            ]
        else:
            raise CompassError(
                f'--mask is {mask.shape[1]} x {mask.shape[0]}; the input is {shp[1]} x {shp[0]}'
            )
    return keep
