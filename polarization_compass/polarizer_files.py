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
The polarizer check's inputs from files: image planes' rays, raw mosaics, Stokes planes and masks.

:func:`check_polarizer_files` reads image files (what ``polarization-compass check-polarizer``
checks), undoes a mirrored readout and runs :func:`.polarizer_check.check_polarizer` on them;
:func:`plane_rays` gives the rays of planes at the sensor's or the superpixels' size.
"""

from __future__ import annotations

import numpy as np

from .errors import CompassError
from .polarizer_check import check_polarizer

__all__ = ['check_polarizer_files', 'plane_rays']


def plane_rays(camera, shape):
    """
    Give the pixel coordinates and rays of image planes: the sensor's size or its superpixels'.

    Parameters
    ----------
    camera : CameraModel
        The camera.
    shape : tuple of int
        (rows, columns) of the planes: the sensor's (H, W) or (H // 2, W // 2).

    Returns
    -------
    tuple
        (x [px], y [px], camera-frame unit rays (3, N), bool mask of the pixels inside the field).

    Raises
    ------
    CompassError
        Planes of any other size.

    """
    from .camera import PixelSelection, select_pixels
    from .estimators.mosaic_input import _grid_rays

    H, W = camera.shape
    shp = tuple(shape)
    if shp == (H, W):
        sp = select_pixels(camera, PixelSelection.full())
        return sp.x_px, sp.y_px, sp.rays_cam, sp.has_ray
    if shp == (H // 2, W // 2):
        return _grid_rays(camera, (1.5, 2.0, W // 2), (1.5, 2.0, H // 2))
    raise CompassError(
        f"the input planes are {shp[1]} x {shp[0]}; the camera file's {W} x {H} sensor needs "
        f'{W} x {H} or {W // 2} x {H // 2} (superpixel)'
    )


def check_polarizer_files(
    paths,
    camera_yaml,
    bits=None,
    mask_path=None,
    sun_altitude_deg=None,
    pitch_deg: float = 0.0,
    roll_deg: float = 0.0,
) -> dict:
    """
    Check a camera file's polarizer convention against the sky in image files.

    Reads the inputs (raw mosaics or Stokes planes, not both) and the mask, and runs
    :func:`check_polarizer` (what ``polarization-compass check-polarizer`` prints).

    Parameters
    ----------
    paths : sequence of str
        Raw mosaics (.png/.tif/.npy) or Stokes planes (.npz, 3-page .tif).
    camera_yaml : str
        ROS camera_calibration file plus ``polarizer:``.
    bits : int, optional
        Significant bits of a raw mosaic in a 16-bit container.
    mask_path : str, optional
        Static mask of the inputs' size (non-zero = sky).
    sun_altitude_deg : float, optional
        Sun altitude [deg]; None fits it per frame.
    pitch_deg, roll_deg : float, default 0
        Known camera pitch and roll [deg].

    Returns
    -------
    dict
        :func:`check_polarizer`'s report plus ``camera_file`` and ``configured_in_file``.

    Raises
    ------
    CompassError
        A frame file, an input that does not fit the camera, or mosaics and Stokes planes mixed.

    """
    from .camera import load_camera_yaml

    cf = load_camera_yaml(camera_yaml)
    cam = cf.camera
    inputs, shapes = _read_inputs(paths, bits, cam.shape)
    masks = None if not mask_path else _masks(mask_path, inputs, shapes, cam.shape)
    if cf.readout_flip:  # the camera and polarizer are the sensor's: read the images as it sees
        inputs, masks = _unflipped(inputs, masks, cf.readout_flip)
    rep = check_polarizer(
        inputs,
        cam,
        cf.layout,
        cf.pol45_toward,
        lambda shape: plane_rays(cam, shape)[2:],
        sun_altitude_deg,
        pitch_deg,
        roll_deg,
        masks,
    )
    rep['camera_file'] = camera_yaml
    rep['configured_in_file'] = cf.layout_given
    return rep


def _unflipped(inputs, masks, readout_flip: str):
    """Undo a mirrored readout on every input and mask (:func:`camera.unflip`)."""
    from .camera import unflip

    def un(a):
        return np.ascontiguousarray(unflip(a, readout_flip))

    out = [(k, un(d) if k == 'mosaic' else tuple(un(a) for a in d), sat) for k, d, sat in inputs]
    return out, None if masks is None else [None if m is None else un(m) for m in masks]


def _read_inputs(paths, bits, sensor_shape):
    """Read the inputs as ``check_polarizer`` takes them, and their shapes; all of one kind."""
    from .real_input import load_polarization_input

    H, W = sensor_shape
    inputs, shapes = [], []
    for path in paths:
        inp = load_polarization_input(path, bits)
        if inp.kind == 'frame':
            raise CompassError(
                f'{path}: check-polarizer reads raw mosaics or Stokes planes, not frame files'
            )
        if inp.kind == 'mosaic':
            if inp.mosaic.shape != (H, W):
                raise CompassError(
                    f'{path}: the mosaic is {inp.mosaic.shape[1]} x {inp.mosaic.shape[0]}, the '
                    'camera '
                    f'file says {W} x {H}'
                )
            inputs.append(('mosaic', inp.mosaic, inp.saturation_level))
            shapes.append(inp.mosaic.shape)
        else:
            shp = inp.stokes[0].shape
            if shp not in ((H, W), (H // 2, W // 2)):
                raise CompassError(
                    f'{path}: Stokes planes of {shp[1]} x {shp[0]} fit neither the {W} x {H} '
                    'sensor '
                    'nor its superpixels'
                )
            inputs.append(('stokes', inp.stokes, None))
            shapes.append(shp)
    if len({k for k, _, _ in inputs}) > 1:
        raise CompassError('check-polarizer: give either raw mosaics or Stokes planes, not both')
    return inputs, shapes


def _masks(mask_path, inputs, shapes, sensor_shape):
    """Read the mask per input; on the superpixel grid for a mosaic (a block is sky if all is)."""
    from .real_input import load_mask

    H, W = sensor_shape
    masks = []
    for shp, (kind, _, _) in zip(shapes, inputs):
        m = load_mask(mask_path, shp)
        if kind == 'mosaic':  # to the superpixel grid: a block is sky when all of it is
            m = m[: 2 * (H // 2), : 2 * (W // 2)].reshape(H // 2, 2, W // 2, 2).all(axis=(1, 3))
        masks.append(m)
    return masks
