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
Solar position: azimuth and altitude of the sun for a UTC time and a site.

Azimuth is clockwise from true North.

Two models
----------
``"spa"`` (default)
    NREL's Solar Position Algorithm (Reda & Andreas 2004, corrigendum 2007), +-0.0003 deg for
    years -2000..6000, taken from pvlib (``pvlib.spa.solar_position``). Why pvlib and not our own
    SPA: it is maintained and tested against NREL's reference implementation, it implements the
    published algorithm term by term, and it is vectorised. We call ``pvlib.spa.solar_position``
    directly with an array of unix times: in pvlib's default numpy mode (``PVLIB_USE_NUMBA`` unset)
    it runs ``solar_position_numpy`` with no numba compile, and it skips the pandas
    ``DatetimeIndex``/``DataFrame`` round trip of ``pvlib.solarposition.spa_python``. Returns the
    topocentric geometric altitude and the refracted (apparent) altitude; azimuth is the same for
    both (refraction acts in the vertical only).
``"paper"``
    The seed paper's eqs 2-10 (Bourges 1985 declination, an equation of time, spherical triangle),
    generalised: UTC plus longitude instead of Beijing time (eq 7 with Beijing time = UTC + 8 h
    reduces to local mean time ``S_d = UTC_h + lon/15``), a fractional day of year
    ``D = day_of_year(1 Jan = 1) + UTC_h / 24`` (0.15 deg great-circle error against SPA over
    2020-2030 with the sun up; an integer day gives up to 0.43 deg), the robust azimuth
    ``A = atan2(sin T, cos T sin L - tan(delta) cos L) + 180 deg`` with the hour angle T wrapped to
    (-180, 180] instead of eq 4's arccos and branch rule, and altitude by arcsin of a clipped
    argument. No refraction: ``apparent_altitude_deg`` is None.

Per-frame use
-------------
A single-time SPA call costs about 2.4 ms, almost all fixed overhead (a batch costs about
6-9 us per time). :class:`SunCache` computes SPA on a grid of times (default every 10 s for 10
minutes ahead) in one call and interpolates the sun's ENU unit vector between grid points,
renormalised. The sun moves on its diurnal circle at most at omega = 15 deg/h, so the distance
between the interpolated and true directions is at most about
``tan(delta) (omega cos(delta) step)^2 / 8`` plus a term of order ``(omega step)^3`` (about
1.4e-6 deg for a 10 s step, as measured).

Times: an aware ``datetime`` (any zone), a naive ``datetime`` (taken as UTC, as elsewhere in the
package), an ISO 8601 string, ``numpy.datetime64``, a pandas ``Timestamp``/``DatetimeIndex``, or a
sequence/array of these. Leap seconds are ignored (POSIX time), as in pvlib.

"""

from __future__ import annotations

from dataclasses import dataclass
import datetime as _dt
import math

import numpy as np

from .conventions import azimuth_altitude_from_enu, enu_direction, wrap_360_deg
from .errors import CompassError
from .solar_paper import _calendar, _paper_model, _US_PER_DAY

__all__ = [
    'SolarError',
    'SunPosition',
    'sun_position',
    'SunCache',
    'MODELS',
    'spa_refraction_deg',
    'to_epoch_us',
]

MODELS = ('spa', 'paper')

#: SPA's validity range (Reda & Andreas 2004).
SPA_YEARS = (-2000, 6000)
#: Site altitudes accepted, m. The standard-atmosphere pressure is undefined above ~44 km.
ALTITUDE_RANGE_M = (-1000.0, 20000.0)
#: pvlib's default refraction at sunrise/sunset (deg), used by SPA's refraction switch.
ATMOS_REFRACT_DEG = 0.5667

_EPOCH_US = np.datetime64(0, 'us')


class SolarError(CompassError):
    """Bad solar-position input: time, latitude, longitude, altitude or model."""


@dataclass(frozen=True)
class SunPosition:
    """
    Hold a sun position in degrees (floats for a scalar time, else arrays of its shape).

    Parameters
    ----------
    azimuth_deg : float or numpy.ndarray
        Azimuth [deg], clockwise from true North, [0, 360).
    altitude_deg : float or numpy.ndarray
        Geometric (true, unrefracted) altitude [deg] in [-90, 90].
    apparent_altitude_deg : float or numpy.ndarray or None
        Altitude with atmospheric refraction [deg], or None for a model without refraction
        (``"paper"``).
    model : str
        The model that computed it (:data:`MODELS`).

    """

    azimuth_deg: object
    altitude_deg: object
    apparent_altitude_deg: object = None
    model: str = 'spa'


# --------------------------------------------------------------------------------------------
# Input handling
# --------------------------------------------------------------------------------------------
def _one_to_us(value) -> int:
    """One time to integer microseconds since 1970-01-01T00:00Z."""
    if isinstance(value, np.datetime64):
        if np.isnat(value):
            raise SolarError('time is NaT (not a time)')
        return int((value.astype('datetime64[us]') - _EPOCH_US).astype(np.int64))
    if isinstance(value, str):
        s = value.strip()
        if s[-1:] in ('Z', 'z'):
            s = s[:-1] + '+00:00'
        try:
            value = _dt.datetime.fromisoformat(s)
        except ValueError:
            raise SolarError(
                f'time {value!r} is not ISO 8601 (e.g. 2019-11-15T06:00:00Z)'
            ) from None
    if isinstance(value, _dt.datetime):
        if value.tzinfo is None:
            value = value.replace(tzinfo=_dt.timezone.utc)
        delta = value - _dt.datetime(1970, 1, 1, tzinfo=_dt.timezone.utc)
        return (delta.days * 86_400 + delta.seconds) * 1_000_000 + delta.microseconds
    if isinstance(value, _dt.date):
        return (value - _dt.date(1970, 1, 1)).days * _US_PER_DAY
    raise SolarError(
        f'time must be a datetime, ISO 8601 string or numpy datetime64, got {type(value).__name__}'
    )


def to_epoch_us(time_utc):
    """
    Convert times to int64 microseconds since the Unix epoch (UTC; leap seconds ignored).

    Parameters
    ----------
    time_utc : datetime, str, numpy.datetime64, pandas.Timestamp or array_like of these
        UTC time(s): an aware ``datetime`` (any zone), a naive one (taken as UTC), an ISO 8601
        string, ``datetime64``, a pandas ``Timestamp``/``DatetimeIndex``, or a sequence/array.

    Returns
    -------
    us : numpy.ndarray
        int64 microseconds since 1970-01-01T00:00Z, the input's shape (1 element for a scalar).
    is_scalar : bool
        The input was a single time.

    Raises
    ------
    SolarError
        No times, NaT, an unreadable string or type.

    """
    # pandas DatetimeIndex / Series with a time zone: convert to naive UTC datetime64 first.
    if (
        hasattr(time_utc, 'tz_convert')
        and hasattr(time_utc, '__len__')
        and getattr(time_utc, 'tz', None) is not None
    ):
        time_utc = time_utc.tz_convert('UTC').tz_localize(None)
    if isinstance(time_utc, (str, _dt.date, np.datetime64)):
        return np.array([_one_to_us(time_utc)], dtype=np.int64), True
    try:
        arr = np.asarray(time_utc)
    except Exception as exc:  # noqa: BLE001 - anything numpy cannot take is a bad time
        raise SolarError(f'cannot read times from {type(time_utc).__name__}: {exc}') from None
    if arr.size == 0:
        raise SolarError('no times given')
    if arr.dtype.kind == 'M':
        flat = arr.reshape(-1).astype('datetime64[us]')
        if np.isnat(flat).any():
            raise SolarError('times contain NaT (not a time)')
        us = (flat - _EPOCH_US).astype(np.int64)
    elif arr.dtype.kind in 'OU':
        us = np.array(
            [_one_to_us(v) for v in arr.reshape(-1)], dtype=np.int64
        )  # loop over times, not pixels
    else:
        raise SolarError(
            f'times must be datetimes, ISO 8601 strings or datetime64, got dtype {arr.dtype}'
        )
    return us.reshape(arr.shape), arr.ndim == 0


def _checked_number(name, v, lo, hi) -> float:
    """
    Return ``float(v)`` when finite and in [lo, hi], else raise a SolarError.

    The SolarError is one line naming ``name``.
    """
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise SolarError(f'{name} must be a number, got {v!r}') from None
    if not math.isfinite(f) or not (lo <= f <= hi):
        raise SolarError(f'{name} must be finite and in [{lo:g}, {hi:g}], got {v!r}')
    return f


def _check_site(latitude_deg, longitude_deg, altitude_m):
    return [
        _checked_number(name, v, lo, hi)
        for name, v, lo, hi in (
            ('latitude_deg', latitude_deg, -90.0, 90.0),
            ('longitude_deg', longitude_deg, -180.0, 180.0),
            ('altitude_m', altitude_m, *ALTITUDE_RANGE_M),
        )
    ]


# --------------------------------------------------------------------------------------------
# NREL SPA via pvlib
# --------------------------------------------------------------------------------------------
def _spa():
    from pvlib import spa  # imported lazily: pvlib pulls in pandas/scipy (~0.5 s)

    return spa


def _default_pressure_hpa(altitude_m):
    from pvlib.atmosphere import alt2pres

    return float(alt2pres(altitude_m)) / 100.0


def _spa_delta_t_s(us, delta_t_s):
    if delta_t_s is not None:
        return float(delta_t_s)
    year, _, _ = _calendar(us)
    month = (
        np.floor_divide(us, _US_PER_DAY)
        .astype('datetime64[D]')
        .astype('datetime64[M]')
        .astype(np.int64)
        % 12
    ) + 1
    return np.asarray(
        _spa().calculate_deltat(year.astype(float), month.astype(float)), dtype=float
    )


def _spa_model(us, lat, lon, alt_m, pressure_hpa, temperature_c, delta_t_s):
    year = _calendar(us)[0]
    if year.min() < SPA_YEARS[0] or year.max() > SPA_YEARS[1]:
        raise SolarError(
            f"model 'spa' is valid for years {SPA_YEARS[0]}..{SPA_YEARS[1]}, "
            f'got {year.min()}..{year.max()}'
        )
    out = _spa().solar_position(
        us.astype(float) / 1e6,
        lat,
        lon,
        alt_m,
        pressure_hpa,
        temperature_c,
        _spa_delta_t_s(us, delta_t_s),
        ATMOS_REFRACT_DEG,
    )
    _app_zenith, _zenith, app_elev, elev, azimuth = (np.asarray(x, dtype=float) for x in out[:5])
    return wrap_360_deg(azimuth), np.clip(elev, -90.0, 90.0), np.clip(app_elev, -90.0, 90.0)


def spa_refraction_deg(geometric_altitude_deg, pressure_hpa, temperature_c):
    """
    Compute SPA's atmospheric refraction correction (pvlib's formula).

    The formula is only evaluated where SPA's switch is on (geometric altitude at least
    -(0.26667 + 0.5667) deg), so no division by (e0 + 5.11) = 0; 0 below.

    Parameters
    ----------
    geometric_altitude_deg : float or array_like
        Geometric (unrefracted) altitude e0 [deg].
    pressure_hpa : float
        Air pressure [hPa].
    temperature_c : float
        Air temperature [degC].

    Returns
    -------
    numpy.ndarray
        Refraction [deg] to add to the geometric altitude; 0 where the switch is off.

    References
    ----------
    .. [1] I. Reda and A. Andreas, "Solar position algorithm for solar radiation applications",
       Solar Energy 76(5): 577-589, 2004 (corrigendum 2007).

    """
    e0 = np.asarray(geometric_altitude_deg, dtype=float)
    on = e0 >= -(0.26667 + ATMOS_REFRACT_DEG)
    safe = np.where(on, e0, 10.0)
    fn = _spa().atmospheric_refraction_correction
    if getattr(_spa(), 'USE_NUMBA', False):  # numba-compiled pvlib takes scalars only
        fn = np.vectorize(fn, otypes=[float])
    return np.where(
        on, fn(float(pressure_hpa), float(temperature_c), safe, ATMOS_REFRACT_DEG), 0.0
    )


# --------------------------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------------------------
def _check_model(model):
    if model not in MODELS:
        raise SolarError(f'model must be one of {", ".join(MODELS)}; got {model!r}')


def _atmosphere(altitude_m, pressure_hpa, temperature_c):
    p = _default_pressure_hpa(altitude_m) if pressure_hpa is None else pressure_hpa
    return (
        _checked_number('pressure_hpa', p, 1.0, 1200.0),
        _checked_number('temperature_c', temperature_c, -90.0, 70.0),
    )


def _package(az, alt, app, scalar, shape, model):
    if scalar:
        return SunPosition(
            float(az.reshape(-1)[0]),
            float(alt.reshape(-1)[0]),
            None if app is None else float(app.reshape(-1)[0]),
            model,
        )
    return SunPosition(
        az.reshape(shape), alt.reshape(shape), None if app is None else app.reshape(shape), model
    )


def sun_position(
    time_utc,
    latitude_deg,
    longitude_deg,
    altitude_m=0.0,
    model='spa',
    *,
    pressure_hpa=None,
    temperature_c=12.0,
    delta_t_s=None,
) -> SunPosition:
    """
    Compute the sun's azimuth and altitude at a UTC time for a site (WGS84).

    Vectorised over times. ``altitude_m`` sets SPA's parallax and, unless ``pressure_hpa`` is
    given, the pressure for refraction (standard atmosphere). The ``paper`` model ignores altitude,
    pressure, temperature and delta T. Never returns NaN.

    Parameters
    ----------
    time_utc : datetime, str, numpy.datetime64, pandas.Timestamp or array_like of these
        UTC time(s): an aware ``datetime`` (any zone), a naive one (taken as UTC), an ISO 8601
        string, ``datetime64``, a pandas ``Timestamp``/``DatetimeIndex``, or a sequence/array.
    latitude_deg : float
        Site latitude [deg], north positive, [-90, 90].
    longitude_deg : float
        Site longitude [deg], east positive, [-180, 180].
    altitude_m : float, default 0
        Site height above sea level [m].
    model : {"spa", "paper"}, default "spa"
        NREL SPA through pvlib, or the paper's eqs 2-10 generalised to UTC (module docstring).
    pressure_hpa : float, optional
        Air pressure for refraction [hPa]; default from ``altitude_m`` (standard atmosphere).
    temperature_c : float, default 12
        Air temperature for refraction [degC].
    delta_t_s : float, optional
        TT - UT1 [s]; default pvlib's ``calculate_deltat`` polynomial (it barely matters: only the
        slow ephemeris uses it).

    Returns
    -------
    SunPosition
        Azimuth [deg, clockwise from North], geometric altitude [deg] and, for SPA, apparent
        altitude [deg]; floats for a scalar time, arrays of the input's shape otherwise.

    Raises
    ------
    SolarError
        Bad time, site, model or atmosphere, or a year outside SPA's -2000..6000.

    References
    ----------
    .. [1] I. Reda and A. Andreas, "Solar position algorithm for solar radiation applications",
       Solar Energy 76(5): 577-589, 2004 (corrigendum 2007).
    .. [2] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 2-10.
    .. [3] B. Bourges, "Improvement in solar declination computation", Solar Energy 35(4):
       367-369, 1985.

    """
    _check_model(model)
    lat, lon, alt_m = _check_site(latitude_deg, longitude_deg, altitude_m)
    us, scalar = to_epoch_us(time_utc)
    shape = us.shape
    flat = us.reshape(-1)
    if model == 'paper':
        az, alt = _paper_model(flat, lat, lon)
        return _package(np.asarray(az), np.asarray(alt), None, scalar, shape, model)
    p, t = _atmosphere(alt_m, pressure_hpa, temperature_c)
    az, alt, app = _spa_model(flat, lat, lon, alt_m, p, t, delta_t_s)
    return _package(az, alt, app, scalar, shape, model)


class SunCache:
    """
    Compute sun positions for a fixed site fast per frame: SPA on a time grid, interpolated.

    ``cache(time_utc)`` (or ``cache.position(time_utc)``) returns the same :class:`SunPosition` as
    :func:`sun_position` (scalar or array times) to within ~1.4e-6 deg great-circle at the default
    10 s grid. The grid covers ``window_s`` seconds from the first query that falls outside it (a
    query before the grid, e.g. a bag played backwards, refills too). Grid points are multiples of
    ``step_s`` since the epoch, so refills are reproducible. Interpolation is linear in the sun's
    ENU unit vector, renormalised (no azimuth wrap, no trouble near the zenith); the apparent
    altitude applies SPA's own refraction formula to the interpolated geometric altitude. The
    ``paper`` model is cheap and is computed directly. Not thread-safe; use one per thread. A call
    raises :class:`SolarError` for bad times or times spanning more than 7 days.

    Parameters
    ----------
    latitude_deg : float
        Site latitude [deg], north positive.
    longitude_deg : float
        Site longitude [deg], east positive.
    altitude_m : float, default 0
        Site height above sea level [m].
    model : {"spa", "paper"}, default "spa"
        Sun position model.
    step_s : float, default 10
        Grid step [s], in [0.001, 600].
    window_s : float, default 600
        Grid length [s], in [2 step_s, 7 days].
    pressure_hpa : float, optional
        Air pressure for refraction [hPa]; default from ``altitude_m``.
    temperature_c : float, default 12
        Air temperature for refraction [degC].
    delta_t_s : float, optional
        TT - UT1 [s]; default pvlib's polynomial.

    Raises
    ------
    SolarError
        Bad site, model, atmosphere, ``step_s`` or ``window_s``.

    References
    ----------
    .. [1] I. Reda and A. Andreas, "Solar position algorithm for solar radiation applications",
       Solar Energy 76(5): 577-589, 2004 (corrigendum 2007).

    """

    def __init__(
        self,
        latitude_deg,
        longitude_deg,
        altitude_m=0.0,
        model='spa',
        *,
        step_s=10.0,
        window_s=600.0,
        pressure_hpa=None,
        temperature_c=12.0,
        delta_t_s=None,
    ):
        _check_model(model)
        self.latitude_deg, self.longitude_deg, self.altitude_m = _check_site(
            latitude_deg, longitude_deg, altitude_m
        )
        self.model = model
        step_s, window_s = float(step_s), float(window_s)
        if not (math.isfinite(step_s) and 1e-3 <= step_s <= 600.0):
            raise SolarError(f'step_s must be in [0.001, 600] s, got {step_s}')
        if not (math.isfinite(window_s) and 2 * step_s <= window_s <= 7 * 86400.0):
            raise SolarError(f'window_s must be in [2 step_s, 7 days], got {window_s}')
        self._step_us = int(round(step_s * 1e6))
        self._n_window = int(math.ceil(window_s * 1e6 / self._step_us))
        self._n = self._n_window
        self.pressure_hpa, self.temperature_c = (
            (None, None)
            if model == 'paper'
            else _atmosphere(self.altitude_m, pressure_hpa, temperature_c)
        )
        self.delta_t_s = delta_t_s
        self._t0_us = None
        self._v_enu = None
        self.refills = 0
        self.queries = 0

    @property
    def span_us(self):
        """(first, last) grid time in epoch microseconds, or None before the first query."""
        return (
            None if self._t0_us is None else (self._t0_us, self._t0_us + self._n * self._step_us)
        )

    def _fill(self, lo_us, hi_us):
        step = self._step_us
        t0 = (
            (lo_us - 2 * step) // step
        ) * step  # two steps of margin for slightly earlier queries
        n = max(self._n_window, int(-(-(hi_us - t0) // step)))
        grid = t0 + step * np.arange(n + 1, dtype=np.int64)
        az, alt, _ = _spa_model(
            grid,
            self.latitude_deg,
            self.longitude_deg,
            self.altitude_m,
            self.pressure_hpa,
            self.temperature_c,
            self.delta_t_s,
        )
        self._t0_us, self._n, self._v_enu = t0, n, enu_direction(az, alt)
        self.refills += 1

    def __call__(self, time_utc) -> SunPosition:
        us, scalar = to_epoch_us(time_utc)
        shape = us.shape
        flat = us.reshape(-1)
        self.queries += 1
        if self.model == 'paper':
            az, alt = _paper_model(flat, self.latitude_deg, self.longitude_deg)
            return _package(np.asarray(az), np.asarray(alt), None, scalar, shape, self.model)
        lo, hi = int(flat.min()), int(flat.max())
        span = self.span_us
        if span is None or lo < span[0] or hi > span[1]:
            if hi - lo > 7 * _US_PER_DAY:
                raise SolarError(
                    'SunCache: times span more than 7 days in one call; use sun_position'
                )
            self._fill(lo, hi)
        rel = flat - self._t0_us
        k = np.minimum(rel // self._step_us, self._n - 1)
        f = ((rel - k * self._step_us) / self._step_us)[:, None]
        v = (1.0 - f) * self._v_enu[k] + f * self._v_enu[k + 1]
        v /= np.linalg.norm(v, axis=-1, keepdims=True)  # |v| >= cos(half a step's angle) > 0.99
        az, alt = azimuth_altitude_from_enu(v)
        az, alt = np.atleast_1d(az), np.atleast_1d(alt)
        app = np.clip(
            alt + spa_refraction_deg(alt, self.pressure_hpa, self.temperature_c), -90.0, 90.0
        )
        return _package(az, alt, app, scalar, shape, self.model)

    position = __call__
