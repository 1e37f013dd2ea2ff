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
The seed paper's solar position model (eqs 2-10), generalised to UTC and longitude.

Bourges' (1985) declination, an equation of time, the hour angle from UTC and longitude and the
spherical triangle to azimuth and altitude, with the generalisations described in :mod:`.solar`'s
docstring (``"paper"``); and :func:`_calendar`, the split of epoch microseconds into year, day of
year and fraction of the day that both models use.
"""

from __future__ import annotations

import numpy as np

from .conventions import wrap_180_deg, wrap_360_deg

_US_PER_DAY = 86_400_000_000


def _calendar(us):
    """
    Split epoch microseconds into year, day of year and fraction of the day (UTC).

    int64 epoch microseconds -> (year, day_of_year with 1 Jan = 1, UTC fraction of the day in [0,
    1)).
    """
    days = np.floor_divide(us, _US_PER_DAY)
    frac = (us - days * _US_PER_DAY) / _US_PER_DAY
    d64 = days.astype('datetime64[D]')
    y64 = d64.astype('datetime64[Y]')
    year = y64.astype(np.int64) + 1970
    doy = (d64 - y64.astype('datetime64[D]')).astype(np.int64) + 1
    return year, doy, frac


# --------------------------------------------------------------------------------------------
# The paper's model (eqs 2-10), generalised to UTC + longitude
# --------------------------------------------------------------------------------------------
def _gregorian_leap_days_since_1985(y):
    """
    Count the leap days in the years 1985 .. y-1 (Gregorian rules).

    Negative before 1985; 1900 and 2100 are not leap years.
    """

    def before(yy):
        return (
            np.floor((yy - 1.0) / 4.0)
            - np.floor((yy - 1.0) / 100.0)
            + np.floor((yy - 1.0) / 400.0)
        )

    return before(y) - before(1985.0)


def _day_angle_rad(year, day_of_year_frac):
    """
    sigma_S = 2 pi (D - D0) / 365.2422 with eq 6's D0.

    Eq 6's ``INT((y - 1985) / 4)`` counts the leap days since 1985 assuming every fourth year is
    one; that equals the Gregorian count for 1901-2100 and is off by one day per skipped century
    year outside it (a 0.13 deg jump of the sun at 1901-01-01 and 2101-01-01), so the Gregorian
    count is used.
    """
    y = np.asarray(year, dtype=float)
    d0 = 79.6764 + 0.2422 * (y - 1985.0) - _gregorian_leap_days_since_1985(y)
    return 2.0 * np.pi * (np.asarray(day_of_year_frac, dtype=float) - d0) / 365.2422


def paper_declination_deg(year, day_of_year_frac):
    """
    Compute the solar declination of eq 5 (Bourges 1985).

    With eq 6's spring-equinox day D0, its leap-day count made Gregorian (see ``_day_angle_rad``).

    Parameters
    ----------
    year : int or array_like
        Calendar year (UTC).
    day_of_year_frac : float or array_like
        Day of year with 1 Jan = 1, plus the UTC fraction of the day (UTC hours / 24).

    Returns
    -------
    float or numpy.ndarray
        Declination [deg].

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 5-6.
    .. [2] B. Bourges, "Improvement in solar declination computation", Solar Energy 35(4):
       367-369, 1985.

    """
    s = _day_angle_rad(year, day_of_year_frac)
    return (
        0.3723
        + 23.2567 * np.sin(s)
        + 0.1149 * np.sin(2 * s)
        - 0.1712 * np.sin(3 * s)
        - 0.758 * np.cos(s)
        + 0.3656 * np.cos(2 * s)
        + 0.0201 * np.cos(3 * s)
    )


def paper_equation_of_time_min(year, day_of_year_frac):
    """
    Compute the equation of time E_t of eq 8 (apparent minus mean solar time).

    Parameters
    ----------
    year : int or array_like
        Calendar year (UTC).
    day_of_year_frac : float or array_like
        Day of year with 1 Jan = 1, plus the UTC fraction of the day (UTC hours / 24).

    Returns
    -------
    float or numpy.ndarray
        E_t [min].

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 8.

    """
    s = _day_angle_rad(year, day_of_year_frac)
    return (
        0.0028
        - 1.9857 * np.sin(s)
        + 9.9059 * np.sin(2 * s)
        - 7.0924 * np.cos(s)
        - 0.6882 * np.cos(2 * s)
    )


def paper_hour_angle_deg(utc_hours, longitude_deg, equation_of_time_min):
    """
    Compute the solar hour angle of eqs 7, 9 and 10 from UTC and longitude.

    ``S_d = UTC_h + lon/15`` (eq 7 without Beijing time), ``S_t = S_d + E_t/60`` (eq 9),
    ``T = 15 (S_t - 12)`` (eq 10), wrapped to (-180, 180].

    Parameters
    ----------
    utc_hours : float or array_like
        UTC time of day [h].
    longitude_deg : float or array_like
        Site longitude [deg], east positive.
    equation_of_time_min : float or array_like
        E_t [min] (:func:`paper_equation_of_time_min`).

    Returns
    -------
    float or numpy.ndarray
        Hour angle T [deg] in (-180, 180], positive in the afternoon (sun west of the meridian).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 7, 9 and 10.

    """
    solar_time_h = (
        np.asarray(utc_hours, dtype=float)
        + np.asarray(longitude_deg, dtype=float) / 15.0
        + np.asarray(equation_of_time_min, dtype=float) / 60.0
    )
    return wrap_180_deg(15.0 * (solar_time_h - 12.0))


def azimuth_altitude_from_equatorial(declination_deg, hour_angle_deg, latitude_deg):
    """
    Compute the sun's azimuth and altitude from declination, hour angle and latitude.

    Eq 3 for the altitude (arcsin of a clipped argument) and a robust replacement of eq 4 for the
    azimuth, ``atan2(sin T, cos T sin L - tan(delta) cos L) + 180 deg``: finite at the poles, at
    the horizon, at noon and for the sun at the zenith (where any azimuth is right).

    Parameters
    ----------
    declination_deg : float or array_like
        Solar declination delta [deg].
    hour_angle_deg : float or array_like
        Hour angle T [deg], positive in the afternoon (sun west of the meridian).
    latitude_deg : float or array_like
        Site latitude L [deg], north positive.

    Returns
    -------
    azimuth_deg : float or numpy.ndarray
        Azimuth [deg] in [0, 360), clockwise from North.
    altitude_deg : float or numpy.ndarray
        Altitude [deg] in [-90, 90].

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 2-4.

    """
    d = np.radians(np.asarray(declination_deg, dtype=float))
    T = np.radians(wrap_180_deg(hour_angle_deg))
    L = np.radians(np.asarray(latitude_deg, dtype=float))
    sin_h = np.clip(np.sin(d) * np.sin(L) + np.cos(d) * np.cos(L) * np.cos(T), -1.0, 1.0)
    altitude = np.degrees(np.arcsin(sin_h))
    azimuth = wrap_360_deg(
        np.degrees(np.arctan2(np.sin(T), np.cos(T) * np.sin(L) - np.tan(d) * np.cos(L))) + 180.0
    )
    return azimuth, altitude


def _paper_model(us, latitude_deg, longitude_deg):
    year, doy, frac = _calendar(us)
    D = doy + frac
    dec = paper_declination_deg(year, D)
    T = paper_hour_angle_deg(24.0 * frac, longitude_deg, paper_equation_of_time_min(year, D))
    return azimuth_altitude_from_equatorial(dec, T, latitude_deg)
