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
Hard cases of the solar position (docs/hard-cases.md).

Those not already covered by test/test_solar.py: the sun on, just above and just below the horizon
(refraction and SPA's switch), within 0.5 deg of the zenith, solar noon from SPA, the poles and the
date line as physical identities, century leap years, and dates that do not exist. Each check uses
a second formula or a physical fact, not the module's own output.
"""

import datetime as dt
import math

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
from polarization_compass.solar import SolarError, spa_refraction_deg, sun_position, SunCache
import pytest

UTC = dt.timezone.utc


def unit(az_deg, alt_deg):
    a, h = np.radians(az_deg), np.radians(alt_deg)
    return np.stack([np.cos(h) * np.sin(a), np.cos(h) * np.cos(a), np.sin(h)], axis=-1)


def great_circle_deg(p, q):
    u, v = unit(p.azimuth_deg, p.altitude_deg), unit(q.azimuth_deg, q.altitude_deg)
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(u, v), axis=-1), np.sum(u * v, axis=-1)))


def seconds(start, n, step_s=1):
    return np.datetime64(start, 's') + (np.arange(n) * step_s).astype('timedelta64[s]')


def bennett_refraction_deg(apparent_deg):
    """
    Return the refraction by Bennett (1982), an independent formula.

    Bennett (1982), a second, independent formula: R = cot(h_a + 7.31 / (h_a + 4.4)) arcmin for the
    apparent altitude h_a (deg), at 1010 hPa and 10 C. SPA uses Saemundsson's inverse form.
    """
    return 1.0 / math.tan(math.radians(apparent_deg + 7.31 / (apparent_deg + 4.4))) / 60.0


# --------------------------------------------------------------------------------------------
# Sun on, just above and just below the horizon
# --------------------------------------------------------------------------------------------
def test_refraction_at_the_true_horizon_agrees_with_bennett():
    """
    Refraction at the true horizon agrees with Bennett's formula.

    Geometric altitude 0 at 1010 hPa, 10 C: SPA lifts the sun by R; Bennett's formula applied to
    the apparent altitude R must give R back (the two formulas agree to ~0.1 arcmin).
    """
    r = float(spa_refraction_deg(0.0, 1010.0, 10.0))
    assert 0.45 < r < 0.52  # ~29 arcmin at the true horizon
    assert r == pytest.approx(bennett_refraction_deg(r), abs=0.005)
    for h in (0.5, 2.0, 10.0, 45.0):  # and above it
        rh = float(spa_refraction_deg(h, 1010.0, 10.0))
        assert rh == pytest.approx(bennett_refraction_deg(h + rh), abs=0.005)


def test_refraction_is_finite_everywhere_and_switches_off_below_minus_0_833():
    """
    Refraction is finite everywhere and switches off below -0.833 deg.

    SPA applies refraction only while the sun's upper limb can be up: geometric altitude >=
    -(0.26667 + 0.5667) deg. Below that it is 0 (a documented jump of ~0.6 deg in apparent
    altitude). The formula's pole at altitude -5.11 deg must never be evaluated.
    """
    h = np.linspace(-90.0, 90.0, 180001)
    r = spa_refraction_deg(h, 1013.25, 12.0)
    # near the zenith h + 10.3 / (h + 5.11) passes 90 deg and the cotangent goes slightly negative
    assert np.all(np.isfinite(r)) and np.all(r >= -1e-4) and np.all(r < 0.8)
    assert np.all(r[h < 89.8] >= 0.0)
    switch = -(0.26667 + 0.5667)
    assert np.all(r[h < switch] == 0.0) and np.all(r[(h >= switch) & (h < 89.8)] > 0.0)
    assert np.all(r[(h >= switch) & (h < switch + 0.01)] > 0.5)
    steps = np.abs(np.diff(r))
    jump = (h[1:] >= switch) & (h[:-1] < switch)
    assert steps[~jump].max() < 1e-3 and 0.5 < steps[jump].max() < 0.7


@pytest.mark.parametrize('model', ['spa', 'paper'])
def test_sunrise_crossing_is_finite_continuous_and_due_east_at_the_equinox(model):
    """
    The sunrise crossing is finite, continuous and due east at the equinox.

    Equinox 2024-03-20 (declination ~ 0): at lat 45 N, lon 0 the sun rises near 06:00 UTC. At the
    geometric horizon cos A = sin(delta) / cos(lat) ~ 0, so the azimuth is 90 deg (+- delta / cos
    lat). One-second samples straddle altitude 0: each step < 15 deg/h * 1 s, and the crossing has
    az ~ 90.
    """
    t = seconds('2024-03-20T05:30:00', 3600)
    p = sun_position(t, 45.0, 0.0, 0.0, model=model)
    assert np.all(np.isfinite(p.altitude_deg)) and np.all(np.isfinite(p.azimuth_deg))
    k = int(np.argmax(p.altitude_deg >= 0.0))
    assert k > 0 and p.altitude_deg[k - 1] < 0.0 <= p.altitude_deg[k]
    assert p.azimuth_deg[k] == pytest.approx(90.0, abs=0.5)
    a = sun_position(t[:-1], 45.0, 0.0, model=model)
    b = sun_position(t[1:], 45.0, 0.0, model=model)
    assert great_circle_deg(a, b).max() < 15.0 / 3600 * 1.01
    if model == 'spa':  # apparent above geometric by ~0.5 deg at the horizon, never below it
        lift = p.apparent_altitude_deg - p.altitude_deg
        assert np.all(lift >= 0) and 0.4 < lift[k] < 0.7


# --------------------------------------------------------------------------------------------
# Sun within 0.5 deg of the zenith; solar noon (hour angle 0)
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('model', ['spa', 'paper'])
def test_sun_passing_within_half_a_degree_of_the_zenith(model):
    """
    The sun passes within half a degree of the zenith smoothly.

    Equator, equinox, solar noon near 12:07 UTC (equation of time ~ -7.5 min): the sun passes
    within ~0.1 deg of the zenith; its azimuth swings by ~180 deg in minutes, but the direction
    moves smoothly (< 15 deg/h per second) and stays finite.
    """
    t = seconds('2024-03-20T11:50:00', 2400)
    p = sun_position(t, 0.0, 0.0, model=model)
    assert p.altitude_deg.max() > 89.5
    assert np.all(np.isfinite(p.azimuth_deg)) and np.all(
        (p.azimuth_deg >= 0) & (p.azimuth_deg < 360)
    )
    a = sun_position(t[:-1], 0.0, 0.0, model=model)
    b = sun_position(t[1:], 0.0, 0.0, model=model)
    assert great_circle_deg(a, b).max() < 15.0 / 3600 * 1.01
    top = p.altitude_deg > 89.5
    swing = np.ptp(p.azimuth_deg[top])
    assert swing > 90.0  # the azimuth really does swing


@pytest.mark.parametrize('lat, expect_az', [(45.0, 180.0), (-45.0, 0.0), (70.0, 180.0)])
def test_spa_azimuth_at_solar_noon_is_due_south_or_north(lat, expect_az):
    """
    Solar noon (hour angle 0) is the time of maximum altitude.

    Fit a parabola to the altitude over
    +-20 min to locate it (independent of the azimuth), then the azimuth there must be 180 deg (sun
    south of the zenith) or 0 deg (north of it) to 0.05 deg.
    """
    t = seconds('2024-06-10T11:40:00', 2401)
    p = sun_position(t, lat, 0.0)
    s = (t - t[0]).astype(float)
    k = int(np.argmax(p.altitude_deg))
    w = slice(max(k - 1200, 0), k + 1200)
    c2, c1, _ = np.polyfit(s[w] - s[k], p.altitude_deg[w], 2)
    t_noon = s[k] - c1 / (2 * c2)
    az = unit(
        p.azimuth_deg, np.zeros_like(p.azimuth_deg)
    )  # interpolate the azimuth as a direction
    i = int(np.floor(t_noon))
    f = t_noon - i
    v = (1 - f) * az[i] + f * az[i + 1]
    az_noon = math.degrees(math.atan2(v[0], v[1])) % 360.0
    assert min(abs(az_noon - expect_az), 360 - abs(az_noon - expect_az)) < 0.05


# --------------------------------------------------------------------------------------------
# Poles, equator, date line
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('model', ['spa', 'paper'])
def test_at_the_pole_the_altitude_is_the_declination_all_day(model):
    """
    At the pole the altitude is the declination all day.

    At the North Pole the altitude equals the declination; on 21 June that is the obliquity, 23.44
    deg (published), and it changes by < 0.01 deg over the day; at the South Pole it is -23.44.
    """
    t = seconds('2024-06-20T12:00:00', 145, 600)
    n = sun_position(t, 90.0, 0.0, model=model)
    s = sun_position(t, -90.0, 0.0, model=model)
    tol = 0.05 if model == 'spa' else 0.4  # the paper's model is ~0.15-0.4 deg off SPA
    assert np.all(np.abs(n.altitude_deg - 23.44) < tol)
    assert np.all(np.abs(s.altitude_deg + 23.44) < tol)
    assert np.ptp(n.altitude_deg) < 0.1
    assert np.all(np.isfinite(n.azimuth_deg)) and np.all(np.isfinite(s.azimuth_deg))


@pytest.mark.parametrize('model', ['spa', 'paper'])
def test_date_line_east_and_west_are_the_same_place(model):
    t = seconds('2024-02-28T18:00:00', 200, 997)
    for lat in (0.0, 52.0, -89.0):
        e = sun_position(t, lat, 180.0, model=model)
        w = sun_position(t, lat, -180.0, model=model)
        assert great_circle_deg(e, w).max() < 1e-9
        near_e = sun_position(t, lat, 179.99999, model=model)
        near_w = sun_position(t, lat, -179.99999, model=model)
        assert great_circle_deg(near_e, near_w).max() < 3e-5  # 2e-5 deg of longitude apart


@given(
    st.datetimes(
        min_value=dt.datetime(1950, 1, 1),
        max_value=dt.datetime(2090, 1, 1),
        timezones=st.just(UTC),
    ),
    st.floats(-90, 90),
    st.floats(-180, 180),
    st.sampled_from(['spa', 'paper']),
)
def test_the_sun_never_jumps(t, lat, lon, model):
    """
    The sun never jumps: one second moves it at most 15 deg/h * 1 s.

    Property: one second later the sun has moved by at most 15 deg/h * 1 s (plus SPA's ~0 parallax
    change) anywhere and at any time, including at the poles, the date line and day/year edges.
    """
    a = sun_position(t, lat, lon, model=model)
    b = sun_position(t + dt.timedelta(seconds=1), lat, lon, model=model)
    assert great_circle_deg(a, b) < 15.0 / 3600 * 1.01


# --------------------------------------------------------------------------------------------
# Leap days and year boundaries (2024 and 2021-2025 are in test_solar.py); century years
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    'model, edge',
    [
        (m, e)
        for m in ('spa', 'paper')
        for e in (
            '2000-02-29T00:00:00',
            '2000-03-01T00:00:00',
            '2100-03-01T00:00:00',
            '2001-01-01T00:00:00',
            '1900-03-01T00:00:00',
        )
    ]
    + [
        (m, e)
        for m in ('spa', 'paper')
        for e in (
            '2101-01-01T00:00:00',
            '1901-01-01T00:00:00',
            '2401-01-01T00:00:00',
            '1801-01-01T00:00:00',
        )
    ],
)
def test_century_leap_rules_do_not_make_the_sun_jump(model, edge):
    """
    The century leap rules do not make the sun jump.

    2000 is a leap year, 1900 and 2100 are not: the day count must follow the Gregorian rules (a
    missed or extra day would jump the declination by up to 0.4 deg and the hour angle by 0).
    """
    t = np.array([edge], dtype='datetime64[s]')
    a = sun_position(t - np.timedelta64(1, 's'), 40.0, 10.0, model=model)
    b = sun_position(t, 40.0, 10.0, model=model)
    assert great_circle_deg(a, b).max() < 0.005


@pytest.mark.parametrize(
    'text',
    [
        '2023-02-29T12:00:00Z',
        '2100-02-29T00:00:00Z',
        '2024-02-30T00:00:00Z',
        '2024-12-31T24:00:00Z',
        '2024-06-21T12:00:60Z',
    ],
)
def test_dates_that_do_not_exist_are_solar_errors(text):
    with pytest.raises(SolarError, match='ISO 8601'):
        sun_position(text, 10.0, 20.0)


def test_cache_across_a_leap_day_and_new_year_matches_direct_calls():
    c = SunCache(60.0, -180.0)
    t = seconds('2024-12-31T23:55:00', 600)
    got = c(t)
    ref = sun_position(t, 60.0, -180.0)
    assert great_circle_deg(got, ref).max() < 1e-4
    t2 = seconds('2024-02-28T23:55:00', 600)
    assert great_circle_deg(c(t2), sun_position(t2, 60.0, -180.0)).max() < 1e-4


def test_paper_leap_day_count_is_eq_6_between_1901_and_2100_and_gregorian_outside():
    """
    The paper's leap day count is eq 6 between 1901 and 2100, Gregorian outside.

    Eq 6's INT((y - 1985) / 4) where every fourth year is a leap year; a calendar count elsewhere.
    """
    import calendar

    from polarization_compass.solar_paper import _gregorian_leap_days_since_1985 as leaps

    for y in range(1901, 2101):
        assert leaps(float(y)) == math.floor((y - 1985) / 4), y
    for y in (1700, 1800, 1900, 2101, 2200, 2401, 2500):
        expected = calendar.leapdays(1985, y) if y >= 1985 else -calendar.leapdays(y, 1985)
        assert leaps(float(y)) == expected, y
