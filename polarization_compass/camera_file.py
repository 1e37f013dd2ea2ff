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
A camera's ``CAMERA.yaml``: the ROS calibration file plus the polarizer, mount and readout.

:func:`load_camera_yaml` reads the lens (:func:`.camera.camera_from_intrinsics`), the polarizer
layout, the ``mount:`` section (:mod:`.mount`) and ``readout_flip``, a camera that mirrors its
readout (:func:`unflip`, :func:`unflipped_camera`).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .camera import camera_from_intrinsics, CameraError, CameraModel, check_intrinsics


@dataclass(frozen=True)
class CameraFile:
    """
    What a ``CAMERA.yaml`` says: the lens and the polarizer layout.

    ``camera`` the :class:`CameraModel`; ``layout`` the 2 x 2 polarizer angles [deg] of the
    top-left block; ``pol45_toward`` the 45 deg polarizer's image direction; ``layout_given`` False
    when the file had no ``polarizer:`` section (the IMX250MZR defaults were used); ``mount`` the
    camera's tilt on the body (:class:`~.mount.Mount`, from a ``mount:`` section) or None;
    ``readout_flip`` the axes the camera mirrors on readout (:data:`READOUT_FLIPS`): then
    ``camera`` and the polarizer describe the *sensor* (the image after :func:`unflip`), the file's
    K having been calibrated on the delivered, mirrored images; ``principal_point_sigma_px`` the
    principal point's 1-sigma [px] the calibration states, or None (not stated: the heading's sigma
    takes a calibration's typical one, :mod:`~.pipeline.optical_centre`).
    """

    camera: CameraModel
    layout: tuple
    pol45_toward: str
    layout_given: bool
    mount: object = None
    readout_flip: str = ''
    principal_point_sigma_px: float | None = None


#: ``readout_flip`` values of a CAMERA.yaml: the image axes the camera mirrors on readout (GenICam
#: ``ReverseX`` = "x", ``ReverseY`` = "y", both = "xy", a 180 deg rotation)
READOUT_FLIPS = ('', 'x', 'y', 'xy')


def unflip(image, readout_flip: str):
    """
    Undo a camera's mirrored readout: the image as the sensor itself sees it.

    Parameters
    ----------
    image : numpy.ndarray
        A delivered image (raw mosaic, a Stokes plane or a mask), rows x columns.
    readout_flip : {"", "x", "y", "xy"}
        The axes the readout mirrors (:data:`READOUT_FLIPS`).

    Returns
    -------
    numpy.ndarray
        A view with the columns (x) and/or rows (y) reversed back.

    """
    a = image
    if 'x' in readout_flip:
        a = a[:, ::-1]
    if 'y' in readout_flip:
        a = a[::-1, :]
    return a


def unflipped_camera(cam: CameraModel, readout_flip: str) -> CameraModel:
    """
    Return the lens model of the unflipped image from a calibration of the delivered one.

    A mirror of the image axis maps pixel u to W + 1 - u (1-based), so the principal point
    mirrors too, and the tangential coefficient of that axis changes sign (p2 for x, p1 for y;
    radial terms are symmetric): the projection is the calibrated one with x -> -x (or y -> -y).

    Parameters
    ----------
    cam : CameraModel
        The intrinsics calibrated on the delivered (mirrored) images.
    readout_flip : {"", "x", "y", "xy"}
        The axes the readout mirrors (:data:`READOUT_FLIPS`).

    Returns
    -------
    CameraModel
        The intrinsics of the image after :func:`unflip` (``cam`` itself without a flip).

    """
    import dataclasses

    if not readout_flip:
        return cam
    cx, cy, d = cam.cx_px, cam.cy_px, list(cam.distortion)
    if 'x' in readout_flip:
        cx = cam.width_px + 1.0 - cx
        if cam.model == 'pinhole' and len(d) >= 4:
            d[3] = -d[3]
    if 'y' in readout_flip:
        cy = cam.height_px + 1.0 - cy
        if cam.model == 'pinhole' and len(d) >= 4:
            d[2] = -d[2]
    return dataclasses.replace(cam, principal_x_px=cx, principal_y_px=cy, distortion=tuple(d))


def _matrix_field(doc: dict, key: str, size: int | None, path: str):
    v = doc.get(key)
    if isinstance(v, dict):
        v = v.get('data')
    if v is None:
        return None
    try:
        a = np.asarray(v, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise CameraError(f'{path}: {key} must be a list of numbers') from None
    if size is not None and a.size != size:
        raise CameraError(f'{path}: {key} must hold {size} numbers, got {a.size}')
    return a


def load_camera_yaml(path) -> CameraFile:
    """
    Read a ROS ``camera_calibration`` YAML file plus the polarizer.

    The file is the one ``camera_info_url`` points at.

    Keys used: ``image_width``, ``image_height``, ``camera_matrix`` (``{rows, cols, data}`` or a
    list), ``distortion_model``, ``distortion_coefficients``; optional ``pixel_pitch_um`` (default
    3.45), ``max_field_angle_deg`` (fisheye, default 90), ``polarizer: {layout: [[90, 45], [135,
    0]], pol45_toward: "+x-y"}`` (default: the Sony IMX250MZR as delivered, see :mod:`demosaic`)
    and ``readout_flip`` (none | x | y | xy: the camera's ReverseX/ReverseY; the polarizer is then
    the sensor's own, and the images are read through :func:`unflip`) and
    ``principal_point_sigma_px`` (the calibration's 1-sigma of cx, cy [px]; default a calibration's
    typical one, :mod:`~.pipeline.optical_centre`).

    Parameters
    ----------
    path : str or path-like
        The YAML file (at most 1 MiB is read).

    Returns
    -------
    CameraFile
        The lens and the polarizer layout.

    Raises
    ------
    CameraError
        Unreadable file, not YAML, missing or unusable keys, implausible intrinsics
        (:func:`check_intrinsics`: principal point more than 10 % off the image centre, fx/fy
        beyond 5 %); one-line reason naming the file.

    """
    from .mosaic import IMX250MZR_LAYOUT, IMX250MZR_POL45, parse_layout, SensorError
    from .safe_load import load_yaml, read_text

    p = str(path)
    # a regular file of at most 1 MiB (a FIFO or /dev/zero is refused), YAML nesting and bad dates
    # one line
    try:
        text = read_text(p, CameraError, 'camera file')
    except CameraError as exc:
        raise CameraError(f'{p}: cannot read camera file ({exc})') from None
    doc = load_yaml(text, p, CameraError)
    if not isinstance(doc, dict):
        raise CameraError(f'{p}: a camera file is a YAML mapping (ROS camera_calibration format)')
    try:
        w, h = int(doc['image_width']), int(doc['image_height'])
    except (KeyError, TypeError, ValueError):
        raise CameraError(f'{p}: needs integer image_width and image_height') from None
    K = _matrix_field(doc, 'camera_matrix', 9, p)
    if K is None:
        raise CameraError(f'{p}: needs camera_matrix (3 x 3, pixels)')
    D = _matrix_field(doc, 'distortion_coefficients', None, p)
    pol = doc.get('polarizer')
    if pol is not None and not isinstance(pol, dict):
        raise CameraError(f'{p}: polarizer must be a mapping with layout and pol45_toward')
    pol = pol or {}
    try:
        lay = parse_layout(
            pol.get('layout', IMX250MZR_LAYOUT), pol.get('pol45_toward', IMX250MZR_POL45)
        )
        cam = camera_from_intrinsics(
            w,
            h,
            K,
            D if D is not None else (),
            doc.get('distortion_model', '') or '',
            float(doc.get('pixel_pitch_um', 3.45)),
            float(doc.get('max_field_angle_deg', 90.0)),
        )
        check_intrinsics(cam)  # as for a camera_info: a K from another mode is refused
        flip = _readout_flip(doc.get('readout_flip', ''))
        pp_sigma = _principal_point_sigma(doc.get('principal_point_sigma_px'), w, h)
    except (SensorError, CameraError, TypeError, ValueError) as exc:
        raise CameraError(f'{p}: {exc}') from None
    cam = unflipped_camera(cam, flip)
    return CameraFile(
        cam,
        lay.angles_deg,
        lay.pol45_toward,
        bool(pol),
        _mount(doc, p),
        readout_flip=flip,
        principal_point_sigma_px=pp_sigma,
    )


def _principal_point_sigma(value, width_px: int, height_px: int) -> float | None:
    """
    Read ``principal_point_sigma_px``: None, or a number in [0, 10 % of the larger image side].

    The bound is the principal point's own (:func:`check_intrinsics`); CameraError otherwise.
    """
    if value is None:
        return None
    limit = 0.1 * max(width_px, height_px)
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or not 0.0 <= value <= limit
    ):
        raise CameraError(
            f'principal_point_sigma_px must be a number of pixels in [0, {limit:g}] (the '
            f"calibration's 1-sigma of cx, cy), got {value!r}"
        )
    return float(value)


def _readout_flip(value) -> str:
    """Read ``readout_flip``: "", "none", "x", "y", "xy" (or "yx"); CameraError otherwise."""
    v = '' if value in (None, False, 'none') else value
    if isinstance(v, str) and ''.join(sorted(v.lower())) in READOUT_FLIPS:
        return ''.join(sorted(v.lower()))
    raise CameraError(f'readout_flip must be one of none, x, y, xy, got {value!r}')


def _mount(doc: dict, path: str):
    """Return the file's ``mount:`` section (:mod:`.mount`), or None without one."""
    from .mount import mount_from_dict, MountError

    try:
        return mount_from_dict(doc['mount'], f'{path}: mount') if 'mount' in doc else None
    except MountError as exc:
        raise CameraError(str(exc)) from None
