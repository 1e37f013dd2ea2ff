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
Photodiode-array recordings: intensities and optional per-sample times.

``.npz``: ``intensities`` float array (S, U, C) and optional ``t_offset_s`` (S,) seconds after a
reference time. CSV: a header line, then one row per sample; columns ``u<unit>_c<channel>``
(0-based, channels in the geometry's ``channels_deg`` order) and optionally ``t_offset_s``. Both
layouts may add, per sample, ``imu_yaw_rad`` (the IMU's yaw, counter-clockwise, any zero) and
``turn_index`` (an integer >= 0 marking the turns in place of a recording; calibrate-mount). Units
with fewer channels than the widest one leave the extra columns out (they read as 0 and are never
used). Readings are intensities (>= 0); negative values and NaN are kept for the estimator to
reject per sample (a sample is never dropped silently), but inf is refused. Readings that are not
measurements (saturated, lone zeros, duplicated channels) are flagged by :func:`reading_flags`.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
import math
import re

import numpy as np

from ..errors import CompassError
from ..safe_load import open_npz

__all__ = [
    'ArrayRecording',
    'ArrayRecordingError',
    'load_array_recording',
    'save_array_recording_npz',
    'save_array_recording_csv',
    'array_sample_from_flat',
    'MAX_SAMPLES',
    'READING_REASONS',
    'reading_flags',
]

MAX_SAMPLES = 1_000_000
_COL = re.compile(r'^u(\d+)_c(\d+)$')
_SAMPLE_KEYS = ('t_offset_s', 'imu_yaw_rad', 'turn_index')


#: Why a unit's readings are not a measurement in one sample (:func:`reading_flags`), plus
#: ``dop_above_1`` (:func:`~.stokes.fit_stokes`).
READING_REASONS = ('bad_value', 'saturated', 'zero_channel', 'duplicated_channels')
#: A channel pair equal in more than this share of a recording's samples is one signal read twice.
_DUPLICATE_SHARE = 0.5
_DUPLICATE_MIN_SAMPLES = 10


class ArrayRecordingError(CompassError):
    """A recording that cannot be read."""


@dataclass
class ArrayRecording:
    """``intensities`` (S, U, C) float64; ``t_offset_s`` (S,) float64 or None."""

    intensities: np.ndarray
    t_offset_s: np.ndarray | None = None
    imu_yaw_rad: np.ndarray | None = None
    turn_index: np.ndarray | None = None

    @property
    def n_samples(self) -> int:
        """Return the number of samples."""
        return int(self.intensities.shape[0])

    def check_against(self, geometry) -> None:
        """
        Check that the recording's shape fits a geometry.

        Parameters
        ----------
        geometry : ArrayGeometry
            The sensor description the readings are for.

        Raises
        ------
        ArrayRecordingError
            The numbers of units or channels do not match.

        """
        _, U, C = self.intensities.shape
        if U != geometry.n_units:
            raise ArrayRecordingError(
                f'the recording has {U} unit(s), the geometry {geometry.n_units}'
            )
        if C < geometry.n_channels:
            raise ArrayRecordingError(
                f'the recording has {C} channel(s) per unit, the geometry needs '
                f'{geometry.n_channels}'
            )


def _validated(inten, t, where: str, imu=None, turn=None) -> ArrayRecording:
    inten = np.asarray(inten)
    if inten.dtype.kind not in 'fiu' or inten.ndim != 3:
        raise ArrayRecordingError(
            f'{where}: intensities must be a numeric array (samples, units, channels), '
            f'got {inten.dtype} with shape {inten.shape}'
        )
    S, U, C = inten.shape
    if not (1 <= S <= MAX_SAMPLES) or not (1 <= U <= 64) or not (2 <= C <= 4):
        raise ArrayRecordingError(
            f'{where}: intensities shape {inten.shape} outside 1-{MAX_SAMPLES} samples, '
            f'1-64 units, 2-4 channels'
        )
    inten = inten.astype(np.float64)
    if np.any(np.isinf(inten)):
        raise ArrayRecordingError(f'{where}: intensities contain inf')
    if t is not None:
        t = np.asarray(t)
        if t.dtype.kind not in 'fiu' or t.shape != (S,):
            raise ArrayRecordingError(
                f'{where}: t_offset_s must be numbers, one per sample ({S}), got shape {t.shape}'
            )
        t = t.astype(np.float64)
        if not np.all(np.isfinite(t)) or np.any(np.abs(t) > 1e9):
            raise ArrayRecordingError(f'{where}: t_offset_s must be finite seconds within +-1e9')
    imu, turn = (_per_sample(where, k, v, S) for k, v in zip(_SAMPLE_KEYS[1:], (imu, turn)))
    return ArrayRecording(inten, t, imu, None if turn is None else turn.astype(np.int64))


def _per_sample(where: str, name: str, v, S: int):
    """Check an optional per-sample column: finite numbers (turn_index: integers 0..1e6)."""
    if v is None:
        return None
    v = np.asarray(v)
    if v.dtype.kind not in 'fiu' or v.shape != (S,) or not np.all(np.isfinite(v)):
        raise ArrayRecordingError(f'{where}: {name} must be finite numbers, one per sample ({S})')
    if name == 'turn_index' and np.any((v != np.round(v)) | (v < 0) | (v > 1e6)):
        raise ArrayRecordingError(f'{where}: turn_index must be integers in 0..1000000')
    return v.astype(np.float64)


#: Longest CSV field read (a number printed with repr() has at most 24 characters).
_MAX_CSV_FIELD_CHARS = 40


def _csv_columns(path, header: list) -> tuple:
    """Return ({(unit, channel): column}, {per-sample key: column}, units, channels)."""
    cols = {}
    named = {}  # per-sample columns: t_offset_s, imu_yaw_rad, turn_index
    for j, h in enumerate(header):
        if h in ('t_offset_s', 'imu_yaw_rad', 'turn_index'):
            named[h] = j
            continue
        m = _COL.match(h)
        if not m:
            raise ArrayRecordingError(
                f'{path}: unknown column {h!r} (expected u<unit>_c<channel>, t_offset_s, '
                'imu_yaw_rad or turn_index)'
            )
        key = (int(m.group(1)), int(m.group(2)))
        if key in cols:
            raise ArrayRecordingError(f'{path}: column {h!r} appears twice')
        cols[key] = j
    if not cols:
        raise ArrayRecordingError(f'{path}: no u<unit>_c<channel> columns')
    U = max(k[0] for k in cols) + 1
    C = max(k[1] for k in cols) + 1
    if U > 64 or C > 4:
        raise ArrayRecordingError(
            f'{path}: columns name {U} units x {C} channels (at most 64 x 4)'
        )
    missing = [u for u in range(U) if not any(k[0] == u for k in cols)]
    if missing:
        raise ArrayRecordingError(f'{path}: no columns for unit(s) {missing}')
    return cols, named, U, C


def _bounded_lines(path, fh, max_chars: int):
    """Yield the lines of ``fh``, refusing one longer than ``max_chars``."""
    for line in fh:
        if len(line) > max_chars:
            raise ArrayRecordingError(f'{path}: a line longer than {max_chars} characters')
        yield line


def _csv_values(path, reader, n_cols: int) -> np.ndarray:
    """Read the data rows into a (samples, columns) float64 array."""
    from array import array

    flat = array('d')
    n = 0
    for line_no, row in enumerate(reader, start=2):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != n_cols:
            raise ArrayRecordingError(
                f'{path}: line {line_no} has {len(row)} fields, the header {n_cols}'
            )
        try:
            flat.extend(float(c) if c.strip() else math.nan for c in row)
        except ValueError:
            raise ArrayRecordingError(f'{path}: line {line_no}: not a number') from None
        n += 1
        if n > MAX_SAMPLES:
            raise ArrayRecordingError(f'{path}: more than {MAX_SAMPLES} samples')
    if not n:
        raise ArrayRecordingError(f'{path}: no samples')
    return np.frombuffer(flat, dtype=np.float64).reshape(n, n_cols)


def _load_csv(path) -> ArrayRecording:
    """
    Read a CSV recording, streamed, bounded by rows x columns from its header.

    At most :data:`MAX_SAMPLES` rows of the header's columns, each at most
    :data:`_MAX_CSV_FIELD_CHARS` characters: a recording of the documented maximum (1e6 samples)
    is read, a file beyond that bound is refused without being read whole.
    """
    from ..safe_load import regular_file

    p = regular_file(path, ArrayRecordingError, 'array recording')
    try:
        with open(p, encoding='utf-8', newline='') as fh:
            first = fh.readline(1 << 16)
            header = [h.strip() for h in next(csv.reader([first]), [])]
            if not header:
                raise ArrayRecordingError(
                    f'{path}: empty CSV (expected a header with u<unit>_c<channel> columns)'
                )
            cols, named, U, C = _csv_columns(path, header)
            line_chars = len(header) * _MAX_CSV_FIELD_CHARS
            if p.stat().st_size > len(first.encode()) + MAX_SAMPLES * line_chars:
                raise ArrayRecordingError(
                    f'{path}: larger than {MAX_SAMPLES} samples of {len(header)} columns can be '
                    '(refused before reading)'
                )
            reader = csv.reader(_bounded_lines(path, fh, line_chars))
            a = _csv_values(path, reader, len(header))
    except UnicodeDecodeError as exc:
        raise ArrayRecordingError(f'{path}: not UTF-8 text (byte {exc.start})') from None
    except csv.Error as exc:
        raise ArrayRecordingError(f'{path}: not a readable CSV ({exc})') from None
    inten = np.zeros((a.shape[0], U, C))
    for (u, c), j in cols.items():
        inten[:, u, c] = a[:, j]
    t, imu, turn = (a[:, named[k]] if k in named else None for k in _SAMPLE_KEYS)
    if t is not None and not np.all(np.isfinite(t)):
        raise ArrayRecordingError(f'{path}: t_offset_s has empty or non-finite values')
    return _validated(inten, t, str(path), imu, turn)


def _check_npz_headers(p: str, h: dict) -> None:
    """Refuse the shapes an .npz recording declares before anything is decompressed."""
    if 'intensities' not in h:
        raise ArrayRecordingError(
            f"{p}: no 'intensities' array (has: {', '.join(sorted(h)) or 'nothing'})"
        )
    shape = h['intensities'].shape
    S, U, C = shape if len(shape) == 3 else (0, 0, 0)
    if not (1 <= S <= MAX_SAMPLES) or not (1 <= U <= 64) or not (2 <= C <= 4):
        raise ArrayRecordingError(
            f'{p}: intensities declares shape {shape}; a recording is (samples, units, channels) '
            f'with 1-{MAX_SAMPLES} samples, 1-64 units, 2-4 channels (refused before reading)'
        )
    if 't_offset_s' in h and h['t_offset_s'].shape != (S,):
        raise ArrayRecordingError(
            f'{p}: t_offset_s declares shape {h["t_offset_s"].shape}, one per sample ({S})'
        )


def load_array_recording(path) -> ArrayRecording:
    """
    Read a recording (``.npz`` or ``.csv`` by extension).

    Parameters
    ----------
    path : str or path-like
        The recording (layouts in the module docstring).

    Returns
    -------
    ArrayRecording
        ``intensities`` (S, U, C) and ``t_offset_s`` (S,) or None.

    Raises
    ------
    ArrayRecordingError
        Any problem with the file, in one line.

    """
    p = str(path)
    if p.lower().endswith('.csv'):
        return _load_csv(path)
    with open_npz(
        path, ArrayRecordingError, 'array recording', check=lambda h: _check_npz_headers(p, h)
    ) as z:
        inten = z['intensities']
        t, imu, turn = (z[k] if k in z.files else None for k in _SAMPLE_KEYS)
    return _validated(inten, t, p, imu, turn)


def save_array_recording_npz(path, intensities, t_offset_s=None, **per_sample) -> None:
    """
    Write the ``.npz`` layout :func:`load_array_recording` reads.

    Parameters
    ----------
    path : str or path-like
        Output file.
    intensities : array_like
        (S, U, C) readings.
    t_offset_s : array_like, optional
        (S,) seconds after the reference time.
    **per_sample : array_like
        Optional (S,) ``imu_yaw_rad`` and ``turn_index``.

    """
    arrays = {'intensities': np.asarray(intensities, dtype=np.float64)}
    if t_offset_s is not None:
        arrays['t_offset_s'] = np.asarray(t_offset_s, dtype=np.float64)
    arrays.update({k: np.asarray(v) for k, v in per_sample.items() if v is not None})
    np.savez(path, **arrays)


def save_array_recording_csv(path, intensities, t_offset_s=None, **per_sample) -> None:
    """
    Write the CSV layout :func:`load_array_recording` reads.

    Parameters
    ----------
    path : str or path-like
        Output file.
    intensities : array_like
        (S, U, C) readings.
    t_offset_s : array_like, optional
        (S,) seconds after the reference time.
    **per_sample : array_like
        Optional (S,) ``imu_yaw_rad`` and ``turn_index``.

    """
    a = np.asarray(intensities, dtype=np.float64)
    S, U, C = a.shape
    extra = {k: np.asarray(v, dtype=float) for k, v in per_sample.items() if v is not None}
    header = (
        (['t_offset_s'] if t_offset_s is not None else [])
        + list(extra)
        + [f'u{u}_c{c}' for u in range(U) for c in range(C)]
    )
    with open(path, 'w', newline='', encoding='utf-8') as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for i in range(S):
            row = ([repr(float(t_offset_s[i]))] if t_offset_s is not None else []) + [
                repr(float(v)) for v in [*(x[i] for x in extra.values()), *a[i].ravel()]
            ]
            w.writerow(row)


def array_sample_from_flat(data, dim_sizes, data_offset: int, geometry) -> np.ndarray:
    """
    Decode one sample (U, C) from a flat message such as ``std_msgs/Float32MultiArray``.

    Layout: row-major units x channels, channels in each unit's ``channels_deg`` order;
    ``layout.dim`` either empty (then ``data`` holds exactly units x channels values after the
    offset) or two dimensions of sizes (units, channels) (labels are not read; the strides are the
    row-major ones the sizes imply).

    Parameters
    ----------
    data : sequence of float
        The message's ``data``.
    dim_sizes : sequence of int
        The sizes of ``layout.dim`` (empty or [units, channels]).
    data_offset : int
        ``layout.data_offset``: values to skip at the start.
    geometry : ArrayGeometry
        The sensor description.

    Returns
    -------
    numpy.ndarray
        (U, C) float64 readings.

    Raises
    ------
    ArrayRecordingError
        A layout that does not fit the geometry, or values that are not finite.

    """
    U, C = geometry.n_units, geometry.n_channels
    sizes = [int(s) for s in dim_sizes]
    if sizes and sizes != [U, C]:
        raise ArrayRecordingError(
            f"layout {sizes} does not match the geometry's units x channels [{U}, {C}]"
        )
    off = int(data_offset)
    a = np.asarray(data, dtype=np.float64).reshape(-1)
    if off < 0 or a.size - off != U * C:
        raise ArrayRecordingError(
            f'{a.size} value(s) after data_offset {off}: expected {U} units x {C} channels'
        )
    out = a[off:].reshape(U, C)
    if not np.all(np.isfinite(out)):
        raise ArrayRecordingError('readings contain NaN or inf')
    return out


def reading_flags(intensities, geometry) -> dict:
    """
    Flag, per sample and unit, readings that are not measurements of the sky.

    ``bad_value``: a channel is NaN or negative. ``saturated``: a channel at or beyond the
    geometry's ``saturation`` limits (none without the key). ``zero_channel``: a channel reads
    exactly 0 while another channel of the unit does not (a dropped or dead reading). ``duplicated_
    channels``: in a recording of at least 10 samples, two channels of a unit read exactly the same
    value in more than half of the samples (one signal wired twice); the unit is flagged in every
    sample. Raw readings are checked, before dark offsets and gains.

    Parameters
    ----------
    intensities : array_like
        (S, U, C) raw readings.
    geometry : ArrayGeometry
        Channels per unit and the ``saturation`` limits.

    Returns
    -------
    dict of str to numpy.ndarray
        For each of :data:`READING_REASONS`, a bool array (S, U); a unit can have several.

    """
    x = np.asarray(intensities, dtype=np.float64)
    S, U, _ = x.shape
    flags = {k: np.zeros((S, U), dtype=bool) for k in READING_REASONS}
    sat = geometry.saturation
    for u, unit in enumerate(geometry.units):
        y = x[:, u, : unit.n_channels]
        finite = np.isfinite(y)
        flags['bad_value'][:, u] = np.any(~finite | (np.where(finite, y, 0.0) < 0.0), axis=1)
        yf = np.where(finite, y, 1.0)
        if sat is not None:
            flags['saturated'][:, u] = np.any((yf <= sat[0]) | (yf >= sat[1]), axis=1)
        zero = finite & (y == 0.0)
        flags['zero_channel'][:, u] = np.any(zero, axis=1) & np.any(finite & (y != 0.0), axis=1)
        flags['duplicated_channels'][:, u] = _duplicated(yf, finite)
    return flags


def _duplicated(y: np.ndarray, finite: np.ndarray) -> bool:
    """Return whether two channels of one unit (readings (S, C)) are one signal read twice."""
    S, C = y.shape
    if S < _DUPLICATE_MIN_SAMPLES:
        return False
    for j in range(C):
        for k in range(j + 1, C):
            same = (y[:, j] == y[:, k]) & finite[:, j] & finite[:, k] & (y[:, j] != 0.0)
            if np.mean(same) > _DUPLICATE_SHARE:
                return True
    return False
