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
Solar position against published figures, the paper's model and SPA.

Solar position: published NREL SPA example, the paper's model against SPA, the robust azimuth
against the paper's eq 4 and against a rotation-matrix derivation, edge cases, the cache, the CLI.
"""

import datetime as dt
import json
import math

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
from polarization_compass.cli import main
from polarization_compass.errors import CompassError
from polarization_compass.solar import SolarError, sun_position, SunCache
from polarization_compass.solar_paper import (
    azimuth_altitude_from_equatorial,
    paper_declination_deg,
    paper_equation_of_time_min,
    paper_hour_angle_deg,
)
import pytest

UTC = dt.timezone.utc
SPA_EXAMPLE = {'latitude_deg': 39.742476, 'longitude_deg': -105.1786, 'altitude_m': 1830.14}
SPA_EXAMPLE_TIME = dt.datetime(
    2003, 10, 17, 12, 30, 30, tzinfo=dt.timezone(dt.timedelta(hours=-7))
)


def unit_vectors(az_deg, alt_deg):
    """ENU unit vectors written out here (not via the package) for great-circle comparisons."""
    a, h = np.radians(az_deg), np.radians(alt_deg)
    return np.stack([np.cos(h) * np.sin(a), np.cos(h) * np.cos(a), np.sin(h)], axis=-1)


def great_circle_deg(az1, alt1, az2, alt2):
    u, v = unit_vectors(az1, alt1), unit_vectors(az2, alt2)
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(u, v), axis=-1), np.sum(u * v, axis=-1)))


def circ_diff_deg(a, b):
    return np.abs((np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0)


# --------------------------------------------------------------------------------------------
# Published reference: Reda & Andreas (2004), NREL SPA, appendix A.5
# --------------------------------------------------------------------------------------------
def test_nrel_spa_published_example():
    """
    The NREL SPA published example.

    17 Oct 2003 12:30:30 UTC-7, 39.742476 N 105.1786 W, 1830.14 m, 820 mbar, 11 C, delta T 67 s:
    topocentric zenith 50.11162 deg, azimuth 194.34024 deg. The published zenith is SPA's
    refraction-corrected one: it matches ``90 - apparent_altitude_deg``, and the geometric zenith
    lies about 0.016 deg (one refraction at 40 deg altitude, 820 mbar) further from it.
    """
    p = sun_position(
        SPA_EXAMPLE_TIME, **SPA_EXAMPLE, pressure_hpa=820.0, temperature_c=11.0, delta_t_s=67.0
    )
    assert p.model == 'spa'
    assert 90.0 - p.apparent_altitude_deg == pytest.approx(50.11162, abs=1e-5)
    assert p.azimuth_deg == pytest.approx(194.34024, abs=1e-5)
    geometric_zenith = 90.0 - p.altitude_deg
    # Refraction from Bennett's rule ~1.02'/tan(h + 10.3/(h + 5.11)) scaled by P and T: ~0.0163 deg
    # here.
    assert 0.012 < geometric_zenith - 50.11162 < 0.020
    assert isinstance(p.azimuth_deg, float) and isinstance(p.apparent_altitude_deg, float)


def test_the_same_instant_in_every_input_form_gives_the_same_sun():
    forms = [
        SPA_EXAMPLE_TIME,
        '2003-10-17T12:30:30-07:00',
        '2003-10-17T19:30:30Z',
        dt.datetime(2003, 10, 17, 19, 30, 30),  # naive = UTC
        np.datetime64('2003-10-17T19:30:30'),
    ]
    ps = [sun_position(t, **SPA_EXAMPLE, delta_t_s=67.0) for t in forms]
    for p in ps[1:]:
        assert p.azimuth_deg == ps[0].azimuth_deg and p.altitude_deg == ps[0].altitude_deg
    arr = sun_position(
        np.array(['2003-10-17T19:30:30', '2003-10-17T19:30:30'], dtype='datetime64[s]'),
        **SPA_EXAMPLE,
        delta_t_s=67.0,
    )
    assert arr.azimuth_deg.shape == (2,)
    np.testing.assert_array_equal(arr.azimuth_deg, ps[0].azimuth_deg)


def test_array_shapes_are_kept_and_scalars_are_floats():
    t = np.arange('2024-06-01T00', '2024-06-01T06', dtype='datetime64[h]').reshape(2, 3)
    for model in ('spa', 'paper'):
        p = sun_position(t, 32.0, 118.8, model=model)
        assert p.azimuth_deg.shape == (2, 3) and p.altitude_deg.shape == (2, 3)
        one = sun_position(t[1, 2], 32.0, 118.8, model=model)
        assert isinstance(one.altitude_deg, float)
        assert one.altitude_deg == pytest.approx(float(p.altitude_deg[1, 2]), abs=1e-12)
    assert sun_position(t, 32.0, 118.8, model='paper').apparent_altitude_deg is None


# --------------------------------------------------------------------------------------------
# The paper's model (eqs 2-10) against SPA over a decade
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('lat, lon', [(0.0, 0.0), (32.0, 118.8), (60.0, -150.0), (-45.0, 170.0)])
def test_paper_model_within_half_a_degree_of_spa_2020_2030(lat, lon):
    """Sampled every 61 min 7 s (drifts through all hours of the day) from 2020 to 2030, sun up."""
    start = np.datetime64('2020-01-01T00:00:00', 's')
    t = start + np.arange(0, 10 * 365 * 86400, 3667).astype('timedelta64[s]')
    spa = sun_position(t, lat, lon, model='spa')
    paper = sun_position(t, lat, lon, model='paper')
    up = spa.altitude_deg > 0.0
    assert up.sum() > 0.4 * t.size
    err = great_circle_deg(
        paper.azimuth_deg, paper.altitude_deg, spa.azimuth_deg, spa.altitude_deg
    )[up]
    assert err.max() < 0.5
    assert err.mean() < 0.1  # measured 0.05-0.06 deg: catches a day or hour offset (0.28 deg)


def test_paper_equation_of_time_and_declination_against_spa_and_the_equinox():
    """
    The paper's equation of time and declination agree with SPA and the equinox.

    Eq 8 against SPA's equation of time (pvlib) over 2024, and eq 5 at the March 2024 equinox (20
    March 03:06 UTC, when the declination is 0).
    """
    from pvlib import spa

    t = np.datetime64('2024-01-01T00:00', 's') + np.arange(0, 366 * 86400, 6 * 3600).astype(
        'timedelta64[s]'
    )
    ux = t.astype(np.int64).astype(float)
    eot_spa = spa.solar_position(ux, 0.0, 0.0, 0.0, 1013.25, 12.0, 69.0, 0.5667)[5]
    doy = (t.astype('datetime64[D]') - np.datetime64('2024-01-01')).astype(int) + 1
    frac = (t - t.astype('datetime64[D]')).astype(float) / 86400.0
    eot_paper = paper_equation_of_time_min(2024, doy + frac)
    # minutes; eq 8 is a 5-term fit: measured max 0.63 min (0.16 deg of hour angle); bound 1 min =
    # 0.25 deg.
    assert np.max(np.abs(eot_paper - eot_spa)) < 1.0
    equinox_D = 80 + (3 + 6 / 60) / 24  # 20 March is day 80 of 2024
    assert abs(paper_declination_deg(2024, equinox_D)) < 0.05


def test_eq7_with_beijing_time_equals_the_utc_generalisation():
    """
    Eq 7 with Beijing time equals the UTC generalisation.

    Eq 7 literally (Beijing hour and minute, UTC+8) gives the same hour angle as UTC + longitude.
    """
    rng = np.random.default_rng(7)
    utc_h = rng.uniform(0, 24, 200)
    lon = rng.uniform(-180, 180, 200)
    eot = rng.uniform(-16, 16, 200)
    bj = (utc_h + 8.0) % 24.0
    S_O, F_O = np.floor(bj), (bj - np.floor(bj)) * 60.0
    S_d = S_O + (F_O - 4.0 * (120.0 - lon)) / 60.0  # eq 7
    T_paper = 15.0 * (S_d + eot / 60.0 - 12.0)  # eqs 9, 10
    T = paper_hour_angle_deg(utc_h, lon, eot)
    assert np.max(circ_diff_deg(T, T_paper)) < 1e-9
    assert T.min() > -180.0 and T.max() <= 180.0


# --------------------------------------------------------------------------------------------
# The robust azimuth form against two other formulas
# --------------------------------------------------------------------------------------------
def _grid():
    d, T, L = np.meshgrid(
        np.linspace(-23.4, 23.4, 25),
        np.linspace(-179.0, 179.0, 181),
        np.linspace(-80.0, 80.0, 33),
        indexing='ij',
    )
    return d.ravel(), T.ravel(), L.ravel()


def test_robust_azimuth_agrees_with_eq4_where_eq4_is_valid():
    d_deg, T_deg, L_deg = _grid()
    az, alt = azimuth_altitude_from_equatorial(d_deg, T_deg, L_deg)
    d, T, L = np.radians(d_deg), np.radians(T_deg), np.radians(L_deg)
    h = np.arcsin(
        np.clip(np.sin(d) * np.sin(L) + np.cos(d) * np.cos(L) * np.cos(T), -1, 1)
    )  # eq 3
    ok = (np.abs(T_deg) > 0.5) & (np.degrees(h) > 1.0) & (np.degrees(h) < 85.0)
    c = (np.sin(d) - np.sin(h) * np.sin(L)) / (np.cos(h) * np.cos(L))
    phi = np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))
    eq4 = np.where(T < 0, phi, 360.0 - phi)
    assert ok.sum() > 20000
    assert np.max(np.abs(alt - np.degrees(h))) < 1e-9
    assert np.max(circ_diff_deg(az[ok], eq4[ok])) < 1e-6


def test_robust_azimuth_agrees_with_rotating_the_equatorial_vector():
    """
    The robust azimuth agrees with rotating the equatorial vector.

    Third derivation: the sun's unit vector in the local equatorial frame (z the celestial pole, x
    the west point, y = z cross x) written in ENU through the latitude. Valid everywhere, including
    below the horizon and at the poles.
    """
    d_deg, T_deg, L_deg = _grid()
    L_deg = np.concatenate([L_deg, np.full(100, 90.0), np.full(100, -90.0)])
    d_deg = np.concatenate([d_deg, np.linspace(-23, 23, 200)])
    T_deg = np.concatenate([T_deg, np.linspace(-180, 180, 200)])
    d, T, L = np.radians(d_deg), np.radians(T_deg), np.radians(L_deg)
    # Equatorial frame: z = celestial pole, x = west point, y = z cross x (meridian, towards the
    # upper culmination point). Hour angle T is measured west from the meridian.
    x_eq, y_eq, z_eq = np.cos(d) * np.sin(T), np.cos(d) * np.cos(T), np.sin(d)
    # In ENU the pole is (0, cos L, sin L), west is (-1, 0, 0), and the upper meridian point is
    # pole x west = (0, -sin L, cos L).
    east = -x_eq
    north = -np.sin(L) * y_eq + np.cos(L) * z_eq
    up = np.cos(L) * y_eq + np.sin(L) * z_eq
    az_ref = np.degrees(np.arctan2(east, north)) % 360.0
    alt_ref = np.degrees(np.arctan2(up, np.hypot(east, north)))
    az, alt = azimuth_altitude_from_equatorial(d_deg, T_deg, L_deg)
    assert np.max(np.abs(alt - alt_ref)) < 1e-9
    well_defined = np.abs(alt_ref) < 89.0
    assert np.max(circ_diff_deg(az, az_ref)[well_defined]) < 1e-6


def test_robust_azimuth_is_finite_at_its_degenerate_points():
    cases = [
        (23.0, 0.0, 23.0),  # sun at the zenith: 0/0 in eq 4
        (10.0, 0.0, 40.0),  # solar noon, T = 0: neither eq 4 branch
        (10.0, 180.0, 40.0),  # lower culmination
        (20.0, 30.0, 90.0),
        (-20.0, 30.0, -90.0),  # poles: cos L = 0
        (0.0, 90.0, 0.0),  # horizon on the equator
        (23.0, -179.99, 80.0),
    ]  # polar day, near midnight
    d, T, L = map(np.array, zip(*cases))
    az, alt = azimuth_altitude_from_equatorial(d, T, L)
    assert np.all(np.isfinite(az)) and np.all(np.isfinite(alt))
    assert np.all((az >= 0.0) & (az < 360.0))
    assert alt[0] == pytest.approx(90.0, abs=1e-6)
    assert az[1] == pytest.approx(180.0, abs=1e-9)  # noon, sun south of the zenith
    assert az[2] == pytest.approx(0.0, abs=1e-9) or az[2] == pytest.approx(360.0, abs=1e-9)
    assert alt[3] == pytest.approx(20.0, abs=1e-9)  # at the pole altitude = declination


# --------------------------------------------------------------------------------------------
# Edge cases: poles, date line, leap days, year boundaries, polar day and night
# --------------------------------------------------------------------------------------------
EDGE_TIMES = np.array(
    [
        '2023-12-31T23:59:59',
        '2024-01-01T00:00:00',
        '2024-02-28T23:59:59',
        '2024-02-29T00:00:00',
        '2024-02-29T12:00:00',
        '2024-03-01T00:00:00',
        '2024-06-21T00:00:00',
        '2024-06-21T12:00:00',
        '2024-12-21T00:00:00',
        '2024-12-21T12:00:00',
        '2024-12-31T23:59:59',
        '2025-01-01T00:00:00',
    ],
    dtype='datetime64[s]',
)


@pytest.mark.parametrize('model', ['spa', 'paper'])
@pytest.mark.parametrize(
    'lat, lon',
    [
        (90.0, 0.0),
        (-90.0, 0.0),
        (0.0, 180.0),
        (0.0, -180.0),
        (78.0, 15.0),
        (-78.0, 166.0),
        (89.999, -180.0),
    ],
)
def test_finite_at_edges(model, lat, lon):
    p = sun_position(EDGE_TIMES, lat, lon, model=model)
    for a in (p.azimuth_deg, p.altitude_deg) + (
        (p.apparent_altitude_deg,) if model == 'spa' else ()
    ):
        assert np.all(np.isfinite(a))
    assert np.all((p.azimuth_deg >= 0.0) & (p.azimuth_deg < 360.0))
    assert np.all(np.abs(p.altitude_deg) <= 90.0)


@pytest.mark.parametrize('model', ['spa', 'paper'])
def test_continuous_across_midnight_leap_day_and_new_year(model):
    """
    The sun is continuous across midnight, a leap day and new year.

    One second apart the sun moves at most 15 deg/h * 1 s = 0.0042 deg: no jump at day/year edges.
    """
    edges = np.array(
        [
            '2024-01-01T00:00:00',
            '2024-02-29T00:00:00',
            '2024-03-01T00:00:00',
            '2025-01-01T00:00:00',
            '2021-01-01T00:00:00',
            '2023-03-01T00:00:00',
        ],
        dtype='datetime64[s]',
    )
    for lat, lon in [(32.0, 118.8), (-45.0, -180.0), (70.0, 180.0)]:
        a = sun_position(edges - np.timedelta64(1, 's'), lat, lon, model=model)
        b = sun_position(edges, lat, lon, model=model)
        assert (
            np.max(great_circle_deg(a.azimuth_deg, a.altitude_deg, b.azimuth_deg, b.altitude_deg))
            < 0.005
        )


@pytest.mark.parametrize('model', ['spa', 'paper'])
def test_polar_day_and_polar_night(model):
    day = np.datetime64('2024-06-21T00:00', 'm') + np.arange(0, 24 * 60, 7).astype(
        'timedelta64[m]'
    )
    north_summer = sun_position(day, 80.0, 20.0, model=model)
    assert north_summer.altitude_deg.min() > 5.0  # 90 - 80 - 23.44 = -13.4 -> up all day
    assert sun_position(day, -80.0, 20.0, model=model).altitude_deg.max() < -5.0
    # The sun circles the sky once: azimuth takes every 45-degree sector.
    sectors = np.unique((north_summer.azimuth_deg // 45).astype(int))
    assert sectors.size == 8


# --------------------------------------------------------------------------------------------
# Property-based: random times and places
# --------------------------------------------------------------------------------------------
_times = st.datetimes(
    min_value=dt.datetime(1901, 1, 1), max_value=dt.datetime(2099, 12, 31), timezones=st.just(UTC)
)


@given(
    t=_times,
    lat=st.floats(-90, 90),
    lon=st.floats(-180, 180),
    alt_m=st.floats(-400, 9000),
    model=st.sampled_from(['spa', 'paper']),
)
def test_random_times_and_places_are_finite_and_in_range(t, lat, lon, alt_m, model):
    p = sun_position(t, lat, lon, alt_m, model=model)
    assert math.isfinite(p.azimuth_deg) and math.isfinite(p.altitude_deg)
    assert 0.0 <= p.azimuth_deg < 360.0
    assert -90.0 <= p.altitude_deg <= 90.0
    if model == 'spa':
        assert math.isfinite(p.apparent_altitude_deg)
        assert (
            -1e-3 <= p.apparent_altitude_deg - p.altitude_deg < 1.0
        )  # refraction lifts (<~0.6 deg)
    else:
        assert p.apparent_altitude_deg is None


# --------------------------------------------------------------------------------------------
# Input validation
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    'kwargs, match',
    [
        ({'latitude_deg': 90.5}, 'latitude'),
        ({'latitude_deg': float('nan')}, 'latitude'),
        ({'longitude_deg': -180.01}, 'longitude'),
        ({'longitude_deg': float('inf')}, 'longitude'),
        ({'altitude_m': 50000.0}, 'altitude'),
        ({'time_utc': 'noon'}, 'ISO 8601'),
        ({'time_utc': np.datetime64('NaT')}, 'NaT'),
        ({'time_utc': 1.7e9}, 'time'),
        ({'time_utc': []}, 'no times'),
        ({'model': 'grena'}, 'model'),
        ({'time_utc': np.datetime64('-3000-01-01')}, 'years'),
        ({'latitude_deg': 'north'}, 'latitude'),
    ],
)
def test_bad_input_raises_a_solar_error(kwargs, match):
    args = {'time_utc': '2024-01-01T00:00Z', 'latitude_deg': 10.0, 'longitude_deg': 20.0}
    args.update(kwargs)
    with pytest.raises(SolarError, match=match) as info:
        sun_position(**args)
    assert isinstance(info.value, CompassError)


# --------------------------------------------------------------------------------------------
# Cache
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    'lat, lon, day',
    [
        (32.0, 118.8, '2024-06-21'),
        (23.44, 0.0, '2024-06-21'),
        (89.9, 45.0, '2024-03-20'),
        (-45.0, -180.0, '2024-12-31'),
        (0.0, 180.0, '2024-02-29'),
    ],
)
def test_cache_matches_direct_calls_to_1e_4_deg(lat, lon, day):
    """
    The cache matches direct calls to 1e-4 deg.

    Frame-by-frame queries (0.1-2 s apart, over 3 h, including one jump back in time) against one
    direct batch call. (23.44 N on 21 June: the sun passes within 0.01 deg of the zenith.)
    """
    rng = np.random.default_rng(3)
    steps_us = rng.integers(100_000, 2_000_000, 9000)
    t = np.datetime64(day + 'T02:00:00', 'us') + np.cumsum(steps_us).astype('timedelta64[us]')
    t[5000:5050] -= np.timedelta64(900, 's')  # a bag replayed from earlier
    cache = SunCache(lat, lon, 120.0)
    got = [cache(ti) for ti in t[::3]]
    ref = sun_position(t[::3], lat, lon, 120.0)
    az = np.array([g.azimuth_deg for g in got])
    alt = np.array([g.altitude_deg for g in got])
    app = np.array([g.apparent_altitude_deg for g in got])
    assert np.max(great_circle_deg(az, alt, ref.azimuth_deg, ref.altitude_deg)) < 1e-4
    assert np.max(np.abs(alt - ref.altitude_deg)) < 1e-4
    assert np.max(np.abs(app - ref.apparent_altitude_deg)) < 1e-4
    not_overhead = ref.altitude_deg < 89.0  # azimuth is ill-defined at the zenith
    assert np.max(circ_diff_deg(az, ref.azimuth_deg)[not_overhead]) < 1e-4
    assert cache.refills <= 3 * 3600 / 600 + 4  # refills per 10 min, not per frame


def test_cache_with_array_queries_and_the_paper_model():
    t = np.datetime64('2024-06-01T00:00', 's') + np.arange(0, 86400, 37).astype('timedelta64[s]')
    c = SunCache(50.0, 8.0)
    got = c(t)  # one array query wider than the window
    ref = sun_position(t, 50.0, 8.0)
    assert got.azimuth_deg.shape == t.shape
    assert (
        np.max(
            great_circle_deg(got.azimuth_deg, got.altitude_deg, ref.azimuth_deg, ref.altitude_deg)
        )
        < 1e-4
    )
    p = SunCache(50.0, 8.0, model='paper')(t)
    ref_p = sun_position(t, 50.0, 8.0, model='paper')
    np.testing.assert_allclose(p.altitude_deg, ref_p.altitude_deg, atol=1e-12)
    assert p.apparent_altitude_deg is None
    with pytest.raises(SolarError):
        SunCache(50.0, 8.0, step_s=0.0)
    with pytest.raises(SolarError):
        SunCache(95.0, 8.0)


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------
def test_cli_sun_prints_json(capsys):
    rc = main(
        [
            'sun',
            '--lat',
            '39.742476',
            '--lon',
            '-105.1786',
            '--time',
            '2003-10-17T12:30:30-07:00',
            '--altitude-m',
            '1830.14',
            '--pressure-hpa',
            '820',
            '--temperature-c',
            '11',
        ]
    )
    out = json.loads(capsys.readouterr().out)
    assert rc == 0
    assert out['time_utc'] == '2003-10-17T19:30:30Z'
    assert (
        out['model'] == 'spa'
        and out['latitude_deg'] == 39.742476
        and out['longitude_deg'] == -105.1786
    )
    assert 90.0 - out['apparent_altitude_deg'] == pytest.approx(
        50.11162, abs=1e-4
    )  # delta T from pvlib here
    assert out['azimuth_deg'] == pytest.approx(194.34024, abs=1e-4)
    rc = main(
        [
            'sun',
            '--lat',
            '32',
            '--lon',
            '118.8',
            '--time',
            '2019-11-15T06:00:00Z',
            '--model',
            'paper',
        ]
    )
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and 'apparent_altitude_deg' not in out and out['model'] == 'paper'
    assert set(out) >= {'azimuth_deg', 'altitude_deg', 'time_utc', 'latitude_deg', 'longitude_deg'}


@pytest.mark.parametrize(
    'argv',
    [
        ['--lat', '91', '--lon', '0', '--time', '2024-01-01T00:00Z'],
        ['--lat', 'nan', '--lon', '0', '--time', '2024-01-01T00:00Z'],
        ['--lat', '10', '--lon', '0', '--time', 'tomorrow'],
    ],
)
def test_cli_sun_bad_arguments_exit_2_with_one_line(argv, capsys):
    rc = main(['sun'] + argv)
    cap = capsys.readouterr()
    assert rc == 2
    assert cap.out == ''
    assert len(cap.err.strip().splitlines()) == 1 and 'error' in cap.err


def test_cli_sun_unparsable_number_exits_2(capsys):
    with pytest.raises(SystemExit) as info:
        main(['sun', '--lat', 'north', '--lon', '0', '--time', '2024-01-01T00:00Z'])
    assert info.value.code == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
