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
A camera's turns in place for ``calibrate-mount``: frames with their IMU yaw, through ``estimate``.

Each frame is read by the estimate road (:func:`~.headings.estimate_file` with the ``CAMERA.yaml``:
the same reader, demosaic, lens and sky mask as ``estimate``), which gives its heading (one method,
``tilt_aware`` by default, for the within-turn scatter) and the observation the mount fit reads:
the angle of polarization (eq 28) at a fixed set of pixel rays (:class:`~.mount_fit.CameraRays`,
:func:`~.mount_fit.camera_samples`). A turn list is a CSV with a header: ``path`` (the frame, as
``estimate`` reads it: a raw mosaic or Stokes planes; relative to the list), ``imu_yaw_rad``
(counter-clockwise, any zero) and optionally ``turn_index`` and ``t_offset_s``.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
import io
from pathlib import Path
import tempfile

import numpy as np
import yaml

from .errors import CompassError
from .mount import Mount, mount_to_dict
from .mount_fit import camera_samples, CameraRays, TurnSamples
from .safe_load import read_text

__all__ = [
    'TurnList',
    'CameraTurns',
    'read_turn_list',
    'camera_yaml_with_mount',
    'camera_turns',
    'turn_headings',
]

#: pixel rays the mount fit reads at most (evenly spread over the lens)
MAX_RAYS = 400


@dataclass
class TurnList:
    """
    The frames of a turn list: paths and per-frame ``imu_yaw_rad``, ``turn_index``, ``t_offset_s``.

    ``t_offset_s`` is None when the list has no such column (all frames at ``--time``).
    """

    paths: list
    imu_yaw_rad: np.ndarray
    turn_index: np.ndarray
    t_offset_s: np.ndarray | None


@dataclass
class CameraTurns:
    """
    What the mount fit and its report need from the frames.

    ``rays`` the fixed pixel rays; ``samples`` their angles per frame; ``bearing_deg`` and ``ok``
    (S,) the frames' headings by ``estimate`` with the level camera file (NaN where none).
    """

    rays: CameraRays
    samples: TurnSamples
    bearing_deg: np.ndarray
    ok: np.ndarray


def read_turn_list(path) -> TurnList:
    """
    Read a turn list (module docstring).

    Parameters
    ----------
    path : str or Path
        The CSV.

    Returns
    -------
    TurnList
        The frames, paths resolved against the list's folder.

    Raises
    ------
    CompassError
        One line: the file, the row and what is wrong.

    """
    p = Path(path)
    text = read_text(p, CompassError, 'turn list')  # bounded; no FIFO, device or directory
    try:
        rows = list(csv.DictReader(io.StringIO(text, newline='')))
    except csv.Error as exc:
        raise CompassError(f'{p}: cannot read the turn list ({exc})') from None
    if not rows or not {'path', 'imu_yaw_rad'} <= set(rows[0]):
        raise CompassError(f'{p}: a turn list needs a header with path and imu_yaw_rad columns')
    has_t = 't_offset_s' in rows[0]
    paths, yaw, turn, t = [], [], [], []
    for i, r in enumerate(rows, start=2):
        try:
            yaw.append(float(r['imu_yaw_rad']))
            turn.append(int(r.get('turn_index') or 0))
            t.append(float(r['t_offset_s']) if has_t else 0.0)
        except (TypeError, ValueError):
            raise CompassError(
                f'{p}: line {i}: imu_yaw_rad, turn_index and t_offset_s must be numbers'
            ) from None
        if not np.isfinite([yaw[-1], t[-1]]).all():
            raise CompassError(f'{p}: line {i}: imu_yaw_rad and t_offset_s must be finite')
        paths.append(str(p.parent / r['path']))
    return TurnList(paths, np.array(yaw), np.array(turn, np.int64), np.array(t) if has_t else None)


def camera_yaml_with_mount(src, mount: Mount | None, dst) -> None:
    """
    Write a copy of a ``CAMERA.yaml`` with its ``mount:`` replaced (None: removed).

    Parameters
    ----------
    src, dst : str or Path
        The camera file read and the one written (comments are not kept).
    mount : Mount or None
        The mount to write.

    """
    doc = yaml.safe_load(read_text(src, CompassError, 'camera file'))
    doc.pop('mount', None)
    if mount is not None:
        doc['mount'] = mount_to_dict(mount)
    with open(dst, 'w', encoding='utf-8') as fh:
        fh.write('# written by polarization-compass calibrate-mount\n')
        yaml.safe_dump(doc, fh, sort_keys=False)


def _estimate(path, camera_yaml, sun_az, sun_alt, pitch, roll, method, seen=None) -> dict:
    """Return ``estimate``'s row of one frame (one method, the given sun and body tilt)."""
    from .headings import estimate_file, EstimateOptions

    opts = EstimateOptions(
        methods=[method],
        camera_yaml=str(camera_yaml),
        sun_azimuth_deg=float(sun_az),
        sun_altitude_deg=float(sun_alt),
        pitch_deg=float(pitch),
        roll_deg=float(roll),
        sky_check=False,
    )
    return estimate_file(path, opts, seen)[0]


def _bearing(row: dict) -> tuple:
    b = row.get('bearing_deg')
    ok = row.get('status') == 'ok' and b is not None
    return (float(b) if ok else np.nan), ok


def turn_headings(paths, camera_yaml, sun_az, sun_alt, pitch, roll, method='tilt_aware'):
    """
    Return the frames' headings by ``estimate`` with a camera file (its mount composed).

    Parameters
    ----------
    paths : list of str
        The frames.
    camera_yaml : str or Path
        The camera file.
    sun_az, sun_alt, pitch, roll : array_like
        (S,) the sun [deg] and the body's pitch and roll [deg] per frame.
    method : str, optional
        The estimator.

    Returns
    -------
    tuple
        ``(bearing_deg, ok)`` arrays (S,); NaN where not ok.

    """
    n = len(paths)
    sun_az, sun_alt, pitch, roll = (
        np.broadcast_to(np.asarray(v, dtype=float), (n,)) for v in (sun_az, sun_alt, pitch, roll)
    )
    out = [
        _bearing(_estimate(p, camera_yaml, sun_az[i], sun_alt[i], pitch[i], roll[i], method))
        for i, p in enumerate(paths)
    ]
    return np.array([b for b, _ in out]), np.array([ok for _, ok in out], dtype=bool)


def _ray_index(obs, max_rays: int) -> np.ndarray:
    """Flat indices of up to ``max_rays`` pixels with a ray, evenly spread (the fit's rays)."""
    rays = np.asarray(obs.rays_cam).reshape(3, -1)
    has = np.nonzero(np.isfinite(rays).all(axis=0) & (np.linalg.norm(rays, axis=0) > 0.5))[0]
    if has.size == 0:
        raise CompassError('the camera file leaves no pixel with a ray')
    return has[:: max(1, has.size // max_rays)][:max_rays]


def camera_turns(
    turns: TurnList,
    camera_yaml,
    sun_az,
    sun_alt,
    pitch=0.0,
    roll=0.0,
    method: str = 'tilt_aware',
    max_rays: int = MAX_RAYS,
    turn_base: int = 0,
) -> CameraTurns:
    """
    Read the frames of a turn list through ``estimate`` with the camera file made level.

    Parameters
    ----------
    turns : TurnList
        The frames and their IMU yaw and turn labels.
    camera_yaml : str or Path
        The camera file (its ``mount:``, if any, is not used: the fit starts level).
    sun_az, sun_alt : array_like
        (S,) the ephemeris sun per frame [deg].
    pitch, roll : float or array_like, optional
        The body's pitch and roll [deg] per frame (the IMU's; 0: level).
    method : str, optional
        The estimator whose headings give the within-turn scatter.
    max_rays : int, optional
        Pixel rays the fit reads at most.
    turn_base : int, optional
        Added to the turn labels (distinct labels across lists).

    Returns
    -------
    CameraTurns
        The fit's rays and samples and the level camera's headings.

    Raises
    ------
    CompassError
        A frame ``estimate`` cannot read, or frames of different sizes.

    """
    n = len(turns.paths)
    sun_az, sun_alt, pitch, roll = (
        np.broadcast_to(np.asarray(v, dtype=float), (n,)) for v in (sun_az, sun_alt, pitch, roll)
    )
    aop, dop, valid, bearing, ok = [], [], [], [], []
    idx = rays = None
    with tempfile.TemporaryDirectory() as tmp:
        level = Path(tmp) / 'level.yaml'
        camera_yaml_with_mount(camera_yaml, None, level)
        for i, path in enumerate(turns.paths):
            seen: dict = {}
            row = _estimate(path, level, sun_az[i], sun_alt[i], pitch[i], roll[i], method, seen)
            obs = seen['observations'][method]
            if idx is None:
                idx = _ray_index(obs, max_rays)
                rays = np.asarray(obs.rays_cam).reshape(3, -1)[:, idx].T
                shape = np.shape(obs.aop_rad)
            elif np.shape(obs.aop_rad) != shape:
                raise CompassError(f'{path}: the frames of a calibration must have one size')
            aop.append(np.ravel(obs.aop_rad)[idx])
            dop.append(np.ravel(obs.dop)[idx])
            valid.append(np.ravel(obs.valid)[idx])
            b, good = _bearing(row)
            bearing.append(b)
            ok.append(good)
    samples = camera_samples(
        np.array(aop),
        np.array(dop),
        np.array(valid),
        turns.imu_yaw_rad,
        turns.turn_index + turn_base,
        sun_az,
        sun_alt,
        pitch,
        roll,
    )
    return CameraTurns(CameraRays(rays), samples, np.array(bearing), np.array(ok, dtype=bool))
