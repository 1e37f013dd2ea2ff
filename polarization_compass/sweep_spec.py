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
What an error-map sweep computes: :class:`SweepSpec` and :func:`parse_range` for its axes.

A spec names the methods, the four axes (sun altitude, yaw, pitch, roll), the scene and the tilt
domain; its :meth:`SweepSpec.digest` identifies the sweep (a store is resumed only by the same
digest) and its chunks are the units of work of :func:`polarization_compass.sweep.run_sweep`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import hashlib
import json
import math

import numpy as np

from .errormap import (
    AXES,
    DEFAULT_TILT_LIMIT_DEG,
    ErrorMapError,
    FORMAT_VERSION,
    STATUS_LEGEND,
    tilt_domain_mask,
)
from .errors import CompassError

__all__ = ['SweepSpec', 'parse_range']


def parse_range(
    text: str,
    name: str = 'range',
    lo: float = -math.inf,
    hi: float = math.inf,
    max_count: int = 100000,
) -> np.ndarray:
    """
    Parse an axis ``"A:B:STEP"`` (B included when B - A is a multiple of STEP) or ``"A"``.

    Parameters
    ----------
    text : str
        The range, in the axis's unit (e.g. deg).
    name : str, default "range"
        Option name for messages (``--<name>``).
    lo, hi : float, default -inf and inf
        Inclusive bounds every value must lie in.
    max_count : int, default 100000
        Most values allowed.

    Returns
    -------
    numpy.ndarray
        float64, strictly increasing (rounded to 1e-9, so 0.1 * 3 is 0.3).

    Raises
    ------
    ErrorMapError
        Not a number or ``A:B:STEP``, non-finite, STEP <= 0, B < A, too many values, or a value
        outside [lo, hi] (the message says which).

    """
    parts = str(text).split(':')
    try:
        nums = [float(p) for p in parts]
    except ValueError:
        raise ErrorMapError(
            f'--{name} must be A:B:STEP or a single number, got {text!r}'
        ) from None
    if not all(math.isfinite(v) for v in nums):
        raise ErrorMapError(f'--{name} must be finite, got {text!r}')
    if len(nums) == 1:
        values = np.array(nums)
    elif len(nums) == 3:
        a, b, step = nums
        if step <= 0:
            raise ErrorMapError(f'--{name}: STEP must be > 0, got {step}')
        if b < a:
            raise ErrorMapError(f'--{name}: B must be >= A, got {text!r}')
        n = int(math.floor((b - a) / step + 1e-9)) + 1
        if n > max_count:
            raise ErrorMapError(f'--{name}: {n} values is more than {max_count}')
        values = a + step * np.arange(n)
        values = np.round(values, 9)  # 0.1 * 3 -> 0.3, not 0.30000000000000004
    else:
        raise ErrorMapError(f'--{name} must be A:B:STEP or a single number, got {text!r}')
    if values.min() < lo or values.max() > hi:
        raise ErrorMapError(f'--{name} values must lie in [{lo}, {hi}], got {text!r}')
    return values.astype(float)


@dataclass
class SweepSpec:
    """
    Describe what a sweep computes: methods and the four axes of the error map.

    Parameters
    ----------
    methods : tuple of str
        Estimator names (for ``array``: photodiode-array methods); not empty.
    sun_altitude_deg, yaw_deg, pitch_deg, roll_deg : array_like
        Axes [deg], each finite and strictly increasing; yaw psi, pitch alpha and roll beta of
        eq 21 (the sun azimuth is 0, so bearing == psi).
    scene : Scene, optional
        :class:`~polarization_compass.scene.Scene` (its attitude, sun and pixel selection are
        overridden per cell); default :func:`~polarization_compass.scene_load.default_scene`.
    knobs : dict, default {}
        ``{method: knobs}``; absent: the estimator class's ``sweep_knobs``, chosen so that errors
        change by < 0.05 deg against full resolution (docs/error-maps.md).
    full_domain : bool, default False
        Compute every (pitch, roll) node, not only |pitch| + |roll| <= ``tilt_limit_deg``.
    tilt_limit_deg : float, default 30
        Tilt domain limit [deg] (the paper's |pitch| + |roll| <= 30).
    support : int, default 2
        Grid nodes outside the limit kept for interpolation inside it.
    array : bool, default False
        Sweep the scene's photodiode array instead of its camera.

    Raises
    ------
    ErrorMapError
        No methods, an axis not finite or not increasing, or array methods that the scene or the
        array do not support.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), section 3 (the simulated
       errors over sun altitude, yaw, pitch and roll).

    """

    methods: tuple
    sun_altitude_deg: np.ndarray
    yaw_deg: np.ndarray
    pitch_deg: np.ndarray
    roll_deg: np.ndarray
    scene: object = None
    knobs: dict = field(default_factory=dict)
    full_domain: bool = False
    tilt_limit_deg: float = DEFAULT_TILT_LIMIT_DEG
    support: int = 2
    array: bool = False  # sweep the scene's photodiode_array instead of its camera

    def __post_init__(self):
        from .scene_load import default_scene

        if self.scene is None:
            self.scene = default_scene()
        self.methods = tuple(self.methods)
        if not self.methods:
            raise ErrorMapError('no methods to sweep')
        for name in AXES:
            a = np.atleast_1d(np.asarray(getattr(self, name), dtype=float))
            if a.size > 1 and not np.all(np.diff(a) > 0):
                raise ErrorMapError(f'{name} must be strictly increasing')
            if not np.all(np.isfinite(a)):
                raise ErrorMapError(f'{name} must be finite')
            setattr(self, name, a)
        from .estimators import registry

        if self.array:
            if self.scene.photodiode_array is None:
                raise ErrorMapError(
                    'an array sweep needs a scene that declares a photodiode_array'
                )
            from .photodiode.heading import array_methods

            bad = [m for m in self.methods if m not in array_methods()]
            if bad:
                raise ErrorMapError(
                    f'method(s) {", ".join(bad)} need an image; a photodiode array supports '
                    f'{", ".join(array_methods())}'
                )
            self.knobs = {
                m: dict(self.knobs.get(m, {})) for m in self.methods
            }  # array knobs, default values
            return
        self.knobs = {
            m: dict(self.knobs[m]) if m in self.knobs else registry.sweep_knobs(m)
            for m in self.methods
        }
        if self.scene.effects:
            self._contiguous_pixels()

    def _contiguous_pixels(self) -> None:
        """
        Tell whether a sweep must read contiguous pixels (scenes with sensor effects).

        A scene with sensor effects renders a mosaic, which needs contiguous pixels (the renderer
        refuses strided selections): such sweeps read every pixel of each method's block (stride
        1), which is slow but what a noisy frame is.
        """
        from .estimators import make_estimator

        cam = self.scene.camera
        for m in self.methods:
            k = self.knobs[m]
            try:
                sel = make_estimator(m, **k).pixels_needed(cam)
            except CompassError:
                continue  # reported when the sweep builds its estimators
            if sel.mode in ('stride', 'region') and sel.stride > 1:
                cand = {**k, 'stride': 1}
                try:
                    make_estimator(m, **cand)
                except CompassError:
                    continue
                self.knobs[m] = cand

    @property
    def shape(self) -> tuple:
        """Shape of the map: (methods, sun altitudes, yaws, pitches, rolls)."""
        return (
            len(self.methods),
            self.sun_altitude_deg.size,
            self.yaw_deg.size,
            self.pitch_deg.size,
            self.roll_deg.size,
        )

    def tilt_mask(self) -> np.ndarray:
        """
        Return the (pitch, roll) nodes to compute.

        Returns
        -------
        numpy.ndarray
            bool (pitches, rolls): every node for ``full_domain``, else the tilt domain and its
            support (:func:`~polarization_compass.errormap.tilt_domain_mask`).

        """
        if self.full_domain:
            return np.ones((self.pitch_deg.size, self.roll_deg.size), dtype=bool)
        return tilt_domain_mask(
            self.pitch_deg, self.roll_deg, self.tilt_limit_deg, support=self.support
        )

    def chunks(self) -> list[tuple[int, int]]:
        """
        Return the chunks of work: (sun altitude, pitch) pairs with a node to compute.

        Returns
        -------
        list of tuple of int
            ``(sun altitude index, pitch index)`` pairs.

        """
        mask = self.tilt_mask()
        return [
            (ia, ip)
            for ia in range(self.sun_altitude_deg.size)
            for ip in range(self.pitch_deg.size)
            if mask[ip].any()
        ]

    def cell_count(self) -> int:
        """
        Return the number of (method, cell) estimates the sweep runs.

        Returns
        -------
        int
            Methods x sun altitudes x yaws x (pitch, roll) nodes of :meth:`tilt_mask`.

        """
        return int(
            len(self.methods)
            * self.sun_altitude_deg.size
            * self.yaw_deg.size
            * self.tilt_mask().sum()
        )

    def to_meta(self) -> dict:
        """
        Return the map's metadata for this sweep.

        Returns
        -------
        dict
            Format and package versions, scene, knobs per method, tilt domain rule, sun azimuth 0,
            the error definition (``fold_axial(estimated psi - true psi)`` [deg] in (-90, 90]) and
            the status legend.

        """
        from . import __version__

        return {
            'format_version': FORMAT_VERSION,
            'package_version': __version__,
            'scene': self.scene.to_dict(),
            'sampling': {m: {'knobs': self.knobs[m]} for m in self.methods},
            'domain': {
                'rule': 'full'
                if self.full_domain
                else '|pitch|+|roll| <= limit, plus the grid nodes within `support` steps of it '
                '(what interpolation inside it reads)',
                'tilt_limit_deg': self.tilt_limit_deg,
                'full_domain': self.full_domain,
                'support': self.support,
            },
            'sun_azimuth_deg': 0.0,
            'error_definition': 'fold_axial(estimated psi - true psi), deg, in (-90, 90]; '
            'bearing == psi',
            'status_codes': STATUS_LEGEND,
        } | ({'sensor': 'photodiode_array'} if self.array else {})

    def digest(self) -> str:
        """
        Return the identity of a sweep for resuming: same digest, same cells and values.

        Returns
        -------
        str
            20 hex digits of the SHA-256 of the metadata (package version excluded) and the axes.

        """
        meta = self.to_meta()
        meta.pop('package_version', None)
        key = {
            'meta': meta,
            'methods': list(self.methods),
            **{k: [float(x) for x in getattr(self, k)] for k in AXES},
        }
        return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:20]
