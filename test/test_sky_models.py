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
Berry-Dennis-Lee sky and CIE radiance: checked against independent computations.

BDL: the paper's own complex function w(zeta) on the stereographic projection (evaluated here in
ENU with numpy complex arithmetic), the Rayleigh model in the limit of zero separation, neutral
points placed by altitude/azimuth arithmetic, winding numbers around loops, and the sign of the
polarization along the solar meridian. CIE: published values (colour-science doctests of ISO
15469), the standard's formula written with spherical trigonometry, and symmetry.
"""

import math
from pathlib import Path

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
from polarization_compass.camera import CameraModel
from polarization_compass.camera_pixels import PixelSelection, select_pixels
from polarization_compass.conventions import (
    CameraAttitude,
    enu_direction,
    evector_cam_from_aop,
    R_enu_cam_from_attitude,
)
from polarization_compass.radiance import (
    CIE_STANDARD_SKIES,
    CIEStandardSky,
    make_radiance_model,
    RadianceError,
)
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import SceneError
from polarization_compass.scene_load import load_scene, scene_from_dict
from polarization_compass.sky import RayleighSky, SkyModelError
from polarization_compass.sky_bdl import BerryDennisLeeSky
from polarization_compass.sky_models import make_sky_model
import pytest

SCENES = Path(__file__).resolve().parents[1] / 'config' / 'scenes'
ZENITH = np.array([0.0, 0.0, 1.0])


def _axial_deg(a_rad, b_rad):
    """Return a - b for axial angles (radians in), degrees in (-90, 90]."""
    d = np.degrees(np.asarray(a_rad, float) - np.asarray(b_rad, float))
    return np.mod(d + 90.0, 180.0) - 90.0


def _random_upper_rays_cam(n, seed):
    rng = np.random.default_rng(seed)
    r = rng.normal(size=(3, n))
    r /= np.linalg.norm(r, axis=0)
    r[2] = np.abs(r[2]) + 0.05  # keep away from the sensor plane (AoP well conditioned)
    r /= np.linalg.norm(r, axis=0)
    return r


def _camera(bearing, pitch, roll, sun_az, sun_alt):
    R = R_enu_cam_from_attitude(bearing, pitch, roll)
    return R, R.T @ enu_direction(sun_az, sun_alt), R[2, :].copy()


def _frame_looking_at(v):
    """Rotation M (columns x, y, z) with z = v: a 'camera' looking straight at v."""
    z = v / np.linalg.norm(v)
    ref = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = ref - np.dot(ref, z) * z
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], axis=1)


# ---------------------------------------------------------------------------------------------
# Independent reference: BDL's w(zeta) on the stereographic projection (ENU, float64, complex)
# ---------------------------------------------------------------------------------------------
def _zeta(v):
    """Stereographic coordinate from the nadir: tan(theta/2) e^{i phi}, X east, Y north."""
    return (v[..., 0] + 1j * v[..., 1]) / (1.0 + v[..., 2])


def bdl_stereographic(sun_az, sun_alt, sep, P_enu, dop_max=1.0):
    """
    Return the BDL E-vector and DoP by the stereographic formula.

    E-vector (ENU, (N, 3)) and DoP from w = -4 prod(z - z_k) / ((1+|z|^2)^2 |z_B-z_F| |z_R-z_A|).
    """
    zb = _zeta(enu_direction(sun_az, sun_alt + sep))  # Babinet (needs sun_alt + sep <= 90)
    zr = _zeta(enu_direction(sun_az, sun_alt - sep))  # Brewster
    zf, za = -1.0 / np.conj(zb), -1.0 / np.conj(zr)  # antipodes: fourth, Arago
    z = _zeta(P_enu)
    w = (
        -4
        * (z - zb)
        * (z - zf)
        * (z - zr)
        * (z - za)
        / ((1 + abs(z) ** 2) ** 2 * abs(zb - zf) * abs(zr - za))
    )
    beta = np.angle(_zeta(enu_direction(sun_az, sun_alt)))
    chi = 0.5 * np.angle(w * np.exp(-2j * beta))  # angle in the local projected basis
    X, Y = z.real, z.imag
    D2 = (1 + X**2 + Y**2) ** 2
    e_X = np.stack([(2 + 2 * Y**2 - 2 * X**2) / D2, -4 * X * Y / D2, -4 * X / D2], -1)  # dP/dX
    e_Y = np.stack([-4 * X * Y / D2, (2 + 2 * X**2 - 2 * Y**2) / D2, -4 * Y / D2], -1)  # dP/dY
    E = np.cos(chi)[:, None] * e_X + np.sin(chi)[:, None] * e_Y
    W = np.abs(w)
    return E, dop_max * W / (2 - W)


@pytest.mark.parametrize(
    'sun_az,sun_alt,sep,att',
    [
        (120.0, 30.0, 18.0, (10.0, -20.0, 5.0)),
        (200.0, 60.0, 18.0, (80.0, 10.0, -10.0)),
        (45.0, 5.0, 25.0, (300.0, 0.0, 0.0)),
        (310.0, 45.0, 10.0, (150.0, 25.0, 15.0)),
    ],
)
def test_bdl_matches_paper_stereographic_formula(sun_az, sun_alt, sep, att):
    R, s_cam, z_cam = _camera(*att, sun_az, sun_alt)
    P_cam = _random_upper_rays_cam(20000, seed=int(sun_az))
    E_enu, dop_ref = bdl_stereographic(sun_az, sun_alt, sep, (R @ P_cam).T, dop_max=0.8)
    E_cam = E_enu @ R  # rows: R^T E
    aop_ref = np.arctan2(E_cam[:, 0], E_cam[:, 1])
    aop, dop, valid = BerryDennisLeeSky(sep, 0.8).polarization(
        s_cam, z_cam, P_cam.astype(np.float32)
    )
    assert valid.all()
    # away from the neutral points (where AoP is undefined) the two agree to float32 precision
    d_np = [
        np.degrees(np.arccos(np.clip(enu_direction(az, alt) @ (R @ P_cam), -1, 1)))
        for az, alt in (
            (sun_az, sun_alt + sep),
            (sun_az, sun_alt - sep),
            (sun_az + 180, -sun_alt + sep),
            (sun_az + 180, -sun_alt - sep),
        )
    ]
    far = np.min(d_np, axis=0) > 0.5
    assert far.sum() > 19000
    assert np.max(np.abs(_axial_deg(aop[far], aop_ref[far]))) < 0.01
    assert np.max(np.abs(dop - dop_ref)) < 2e-6


@pytest.mark.parametrize(
    'sun_az,sun_alt,att',
    [
        (120.0, 30.0, (10.0, -20.0, 5.0)),
        (10.0, 75.0, (200.0, 15.0, -25.0)),
        (260.0, 2.0, (90.0, 0.0, 30.0)),
    ],
)
def test_bdl_reduces_to_rayleigh(sun_az, sun_alt, att):
    R, s_cam, z_cam = _camera(*att, sun_az, sun_alt)
    P = _random_upper_rays_cam(20000, seed=7).astype(np.float32)
    aop_r, dop_r, _ = RayleighSky(1.0).polarization(s_cam, z_cam, P)
    cos_g = s_cam @ P.astype(float)
    away = np.abs(cos_g) < math.cos(math.radians(3.0))  # AoP undefined at the sun and anti-sun
    for sep in (1e-3, 0.0):
        aop_b, dop_b, _ = BerryDennisLeeSky(sep, 0.6).polarization(s_cam, z_cam, P)
        assert np.max(np.abs(_axial_deg(aop_b[away], aop_r[away]))) < 1e-3
        assert np.max(np.abs(dop_b / 0.6 - dop_r)) < 1e-5  # same DoP shape after normalising
    # and the DoP is the textbook sin^2 g / (1 + cos^2 g), computed here in float64
    assert np.max(np.abs(dop_b / 0.6 - (1 - cos_g**2) / (1 + cos_g**2))) < 1e-5


NEUTRAL_SUNS = [(0.0, 10.0), (135.0, 30.0), (250.0, 55.0), (80.0, -3.0)]


def _neutral_points_by_angles(sun_az, sun_alt, sep):
    """
    Return neutral point positions from altitude/azimuth arithmetic.

    Positions from altitude/azimuth arithmetic along the solar meridian (not the model's helper).
    """
    return {
        'babinet': enu_direction(sun_az, sun_alt + sep),  # above the sun
        'brewster': enu_direction(sun_az, sun_alt - sep),  # below the sun
        'arago': enu_direction(sun_az + 180.0, -sun_alt + sep),  # above the anti-sun
        'fourth': enu_direction(sun_az + 180.0, -sun_alt - sep),
    }  # below the anti-sun


@pytest.mark.parametrize('sun_az,sun_alt', NEUTRAL_SUNS)
def test_bdl_neutral_points_have_zero_dop_at_their_positions(sun_az, sun_alt):
    sep = 18.0
    model = BerryDennisLeeSky(sep, 0.75)
    R, s_cam, z_cam = _camera(33.0, -12.0, 7.0, sun_az, sun_alt)
    pts = _neutral_points_by_angles(sun_az, sun_alt, sep)
    helper = model.neutral_points_cam(s_cam, z_cam)
    for name, v_enu in pts.items():
        v_cam = R.T @ v_enu
        np.testing.assert_allclose(helper[name], v_cam, atol=1e-12)
        M = _frame_looking_at(v_cam)
        # the point itself and rings at 0.5, 2 and 5 deg around it
        rays = [np.array([0.0, 0.0, 1.0])]
        phis = np.linspace(0, 2 * np.pi, 24, endpoint=False)
        for rho in (0.5, 2.0, 5.0):
            r = math.radians(rho)
            rays += list(
                np.stack(
                    [
                        math.sin(r) * np.cos(phis),
                        math.sin(r) * np.sin(phis),
                        np.full(phis.size, math.cos(r)),
                    ],
                    axis=1,
                )
            )
        rays_cam = (M @ np.array(rays).T).astype(np.float32)
        _, dop, _ = model.polarization(s_cam, z_cam, rays_cam)
        assert dop[0] < 2e-6, name
        ring = dop[1:].reshape(3, -1)
        assert np.all(ring[0] > 0) and np.all(ring[1].min() > ring[0].max() * 0.5)
        assert ring[2].mean() > ring[1].mean() > ring[0].mean() > dop[0]
    # the sun and anti-sun are NOT neutral points in BDL (they are in Rayleigh): there |w| =
    # sin^2(sep)
    _, dop_sun, _ = model.polarization(
        s_cam, z_cam, np.stack([s_cam, -s_cam], 1).astype(np.float32)
    )
    w = math.sin(math.radians(sep)) ** 2
    np.testing.assert_allclose(dop_sun, 0.75 * w / (2 - w), rtol=1e-5)


def _winding_deg(model, s_cam, z_cam, centre_cam, radius_deg, n=240):
    """
    Return the total rotation of the AoP (deg) around a loop about centre.

    Total rotation of the AoP (deg) around a loop of angular radius ``radius_deg`` about centre.
    """
    M = _frame_looking_at(centre_cam)
    phis = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = math.radians(radius_deg)
    loop = np.stack(
        [math.sin(r) * np.cos(phis), math.sin(r) * np.sin(phis), np.full(n, math.cos(r))]
    )
    aop, _, _ = model.polarization(M.T @ s_cam, M.T @ z_cam, loop.astype(np.float32))  # camera = M
    steps = _axial_deg(np.roll(aop, -1), aop)
    assert np.max(np.abs(steps)) < 45.0  # loop finely enough sampled to unwrap
    return float(np.sum(steps))


@pytest.mark.parametrize('sun_az,sun_alt', [(0.0, 10.0), (135.0, 30.0), (250.0, 55.0)])
def test_bdl_neutral_points_have_index_one_half(sun_az, sun_alt):
    sep = 18.0
    model = BerryDennisLeeSky(sep, 0.75)
    R, s_cam, z_cam = _camera(0.0, 0.0, 0.0, sun_az, sun_alt)
    turns = {}
    for name, v_enu in _neutral_points_by_angles(sun_az, sun_alt, sep).items():
        turns[name] = _winding_deg(model, s_cam, z_cam, R.T @ v_enu, 4.0)
        assert abs(abs(turns[name]) - 180.0) < 1e-3, (name, turns[name])
    assert len({round(t) for t in turns.values()}) == 1  # all four have the same index (+1/2)
    # a loop around the sun enclosing Babinet and Brewster: index 1, the same as Rayleigh's sun
    around_sun = _winding_deg(model, s_cam, z_cam, s_cam, 30.0)
    rayleigh_sun = _winding_deg(RayleighSky(), s_cam, z_cam, s_cam, 30.0)
    assert abs(around_sun - 2 * turns['babinet']) < 1e-3 and abs(rayleigh_sun - around_sun) < 1e-3
    # a loop enclosing nothing: no net rotation
    off = R.T @ enu_direction(sun_az + 90.0, 40.0)
    assert abs(_winding_deg(model, s_cam, z_cam, off, 10.0)) < 1e-3


def test_bdl_negative_polarization_between_babinet_and_brewster():
    """
    BDL has negative polarization between the Babinet and Brewster points.

    On the solar meridian the E-vector lies in the meridian plane between the two neutral points
    near the sun (and near the anti-sun), and perpendicular to it elsewhere.
    """
    sun_az, sun_alt, sep = 90.0, 30.0, 18.0
    R, s_cam, z_cam = _camera(0.0, 0.0, 0.0, sun_az, sun_alt)  # level camera
    n_merid_cam = R.T @ np.cross(enu_direction(sun_az, sun_alt), ZENITH)
    n_merid_cam /= np.linalg.norm(n_merid_cam)
    alts = np.array([sun_alt + 9.0, sun_alt - 9.0, sun_alt + 30.0, 85.0])  # on the meridian
    rays_cam = (R.T @ enu_direction(np.full(4, sun_az), alts).T).astype(np.float32)
    aop, dop, _ = BerryDennisLeeSky(sep, 1.0).polarization(s_cam, z_cam, rays_cam)
    E = evector_cam_from_aop(aop.astype(float), rays_cam.T.astype(float))
    along_normal = np.abs(E @ n_merid_cam)
    np.testing.assert_allclose(along_normal[:2], 0.0, atol=1e-5)  # E in the meridian plane
    np.testing.assert_allclose(along_normal[2:], 1.0, atol=1e-5)  # E perpendicular to it
    # near the anti-sun (below the horizon here): Arago at -12 deg, fourth at -48 deg
    arago_side = (R.T @ enu_direction(sun_az + 180.0, -sun_alt + 5.0)).astype(np.float32)[:, None]
    aop2, _, _ = BerryDennisLeeSky(sep, 1.0).polarization(s_cam, z_cam, arago_side)
    E2 = evector_cam_from_aop(aop2.astype(float), arago_side.T.astype(float))
    assert abs(float(E2[0] @ n_merid_cam)) < 1e-5


def test_bdl_sun_at_zenith_and_low_sun_are_finite():
    model = BerryDennisLeeSky(18.0, 0.75)
    P = _random_upper_rays_cam(5000, seed=3).astype(np.float32)
    for sun in (ZENITH, -ZENITH, enu_direction(10.0, 0.0), enu_direction(10.0, -20.0)):
        aop, dop, valid = model.polarization(sun, ZENITH, P)
        assert np.isfinite(aop).all() and np.isfinite(dop).all() and valid.all()
        assert dop.min() >= 0 and dop.max() <= 0.75 + 1e-6
    # sun at the zenith: Babinet/Brewster on a ring of 18 deg around it, DoP 0 at both
    pts = model.neutral_points_cam(ZENITH, ZENITH)
    _, d, _ = model.polarization(
        ZENITH, ZENITH, np.stack([pts['babinet'], pts['brewster']], 1).astype(np.float32)
    )
    assert d.max() < 2e-6
    assert abs(float(np.degrees(np.arccos(pts['babinet'][2]))) - 18.0) < 1e-9


def test_bdl_validity_limits_match_rayleigh_masks():
    """Same validity rule as Rayleigh: outside the sun disk, above min altitude, DoP >= min DoP."""
    R, s_cam, z_cam = _camera(20.0, -25.0, 10.0, 160.0, 35.0)
    P = _random_upper_rays_cam(20000, seed=11).astype(np.float32)
    limits = (math.cos(math.radians(10.0)), math.sin(math.radians(15.0)), 0.1)
    aop, dop, valid = BerryDennisLeeSky(18.0, 0.75).polarization(s_cam, z_cam, P, limits)
    _, dop_all, _ = BerryDennisLeeSky(18.0, 0.75).polarization(s_cam, z_cam, P)
    g = np.degrees(np.arccos(np.clip(s_cam @ P.astype(float), -1, 1)))
    alt = np.degrees(np.arcsin(np.clip(z_cam @ P.astype(float), -1, 1)))
    expect = (g >= 10.0 + 1e-3) & (alt >= 15.0 + 1e-3) & (dop_all >= 0.1 + 1e-6)
    clear = (
        (np.abs(g - 10.0) > 1e-3) & (np.abs(alt - 15.0) > 1e-3) & (np.abs(dop_all - 0.1) > 1e-6)
    )
    assert np.array_equal(valid[clear], expect[clear])
    assert np.all(aop[~valid] == 0) and np.all(dop[~valid] == 0)
    assert np.array_equal(dop[valid], dop_all[valid])


@pytest.mark.parametrize(
    'cfg',
    [
        {'model': 'berry_dennis_lee', 'separation_deg': -1.0},
        {'model': 'berry_dennis_lee', 'separation_deg': 40.5},
        {'model': 'berry_dennis_lee', 'separation_deg': float('nan')},
        {'model': 'berry_dennis_lee', 'separation_deg': 'abc'},
        {'model': 'berry_dennis_lee', 'separation_deg': None},
        {'model': 'berry_dennis_lee', 'dop_max': 0.0},
        {'model': 'berry_dennis_lee', 'dop_max': 1.5},
        {'model': 'berry_dennis_lee', 'dop_max': 'x'},
        {'model': 'berry_dennis_lee', 'separation': 18},
    ],
)
def test_bdl_rejects_bad_parameters(cfg):
    with pytest.raises(SkyModelError):
        make_sky_model(cfg)


def test_bdl_registered_and_params_round_trip():
    m = make_sky_model({'model': 'berry_dennis_lee', 'separation_deg': 15, 'dop_max': 0.5})
    assert isinstance(m, BerryDennisLeeSky)
    assert m.params() == {'model': 'berry_dennis_lee', 'separation_deg': 15.0, 'dop_max': 0.5}
    assert isinstance(make_sky_model(m.params()), BerryDennisLeeSky)
    assert (
        make_sky_model({'model': 'berry_dennis_lee', 'separation_deg': 40}).separation_deg == 40.0
    )


_GRID = select_pixels(CameraModel(), PixelSelection.grid(24, 20)).rays_cam


@given(
    sun_az=st.floats(0, 360),
    sun_alt=st.floats(-10, 90),
    bearing=st.floats(0, 360),
    pitch=st.floats(-60, 60),
    roll=st.floats(-60, 60),
    sep=st.floats(0, 40),
    dop_max=st.floats(0.05, 1.0),
    excl=st.floats(0, 20),
    min_alt=st.floats(-10, 30),
    min_dop=st.floats(0, 0.3),
)
def test_bdl_outputs_always_in_range(
    sun_az, sun_alt, bearing, pitch, roll, sep, dop_max, excl, min_alt, min_dop
):
    _, s_cam, z_cam = _camera(bearing, pitch, roll, sun_az, sun_alt)
    limits = (math.cos(math.radians(excl)), math.sin(math.radians(min_alt)), min_dop)
    aop, dop, valid = BerryDennisLeeSky(sep, dop_max).polarization(s_cam, z_cam, _GRID, limits)
    assert aop.dtype == np.float32 and dop.dtype == np.float32 and valid.dtype == np.bool_
    assert np.isfinite(aop).all() and np.isfinite(dop).all()
    assert np.all(aop >= -np.pi / 2) and np.all(aop < np.pi / 2)
    assert np.all(dop >= 0) and np.all(dop <= dop_max * (1 + 1e-6))
    assert np.all(aop[~valid] == 0) and np.all(dop[~valid] == 0)


# ---------------------------------------------------------------------------------------------
# CIE standard general sky
# ---------------------------------------------------------------------------------------------
def cie_by_hand(sky_type, Z_deg, az_deg, Zs_deg, azs_deg):
    """ISO 15469 L/Lz with spherical trigonometry in float64 (elements above the horizon)."""
    a, b, c, d, e, _ = CIE_STANDARD_SKIES[sky_type]
    Z, az, Zs, azs = (np.radians(np.asarray(v, float)) for v in (Z_deg, az_deg, Zs_deg, azs_deg))
    chi = np.arccos(
        np.clip(np.cos(Zs) * np.cos(Z) + np.sin(Zs) * np.sin(Z) * np.cos(az - azs), -1, 1)
    )

    def f(x):
        return 1 + c * (np.exp(d * x) - np.exp(d * np.pi / 2)) + e * np.cos(x) ** 2

    def phi(z):
        return 1 + a * np.exp(b / np.cos(z))

    return f(chi) * phi(Z) / (f(Zs) * phi(0.0))


def _cie_enu(model, Z_deg, az_deg, Zs_deg, azs_deg):
    """
    Evaluate a radiance model with ENU as its frame.

    Any frame works: only sun and zenith matter.
    """
    rays = enu_direction(np.atleast_1d(az_deg), 90.0 - np.atleast_1d(Z_deg)).T.astype(np.float32)
    return model.radiance(enu_direction(azs_deg, 90.0 - Zs_deg), ZENITH, rays)


def test_cie_published_values():
    # colour-science, sky_luminance_distribution_CIE2003 doctests: Z=45, alpha=180, Zs=30,
    # alpha_s=0
    assert _cie_enu(CIEStandardSky(1), 45.0, 180.0, 30.0, 0.0)[0] == pytest.approx(
        0.8325846, abs=2e-6
    )
    assert _cie_enu(CIEStandardSky(12), 45.0, 180.0, 30.0, 0.0)[0] == pytest.approx(
        0.4544524, abs=2e-6
    )
    # table row 12 of ISO 15469 as quoted by the same source
    m = make_radiance_model({'model': 'cie_clear'})
    assert (m.a, m.b, m.c, m.d, m.e, m.sky_type) == (-1.0, -0.32, 10.0, -3.0, 0.45, 12)


@pytest.mark.parametrize('sky_type', sorted(CIE_STANDARD_SKIES))
def test_cie_matches_formula_by_hand_for_every_type(sky_type):
    rng = np.random.default_rng(sky_type)
    model = CIEStandardSky(sky_type)
    for Zs, azs in ((30.0, 0.0), (60.0, 135.0), (85.0, 250.0), (5.0, 40.0)):
        Z = rng.uniform(0, 89.5, 400)
        az = rng.uniform(0, 360, 400)
        got = _cie_enu(model, Z, az, Zs, azs)
        ref = cie_by_hand(sky_type, Z, az, Zs, azs)
        # float32 acos near the sun: d(chi) ~ 1e-7 / sin(chi); compare relative, away from the sun
        # disk
        np.testing.assert_allclose(got, ref, rtol=3e-5)
        assert _cie_enu(model, 0.0, 17.0, Zs, azs)[0] == pytest.approx(
            1.0, abs=2e-6
        )  # L(zenith) = 1


def test_cie_symmetry_and_sun_side_brighter():
    model = make_radiance_model({'model': 'cie_clear', 'type': 12})
    Zs, azs = 50.0, 120.0
    for Z in (20.0, 45.0, 70.0, 85.0):
        for dpsi in (10.0, 60.0, 120.0, 170.0):  # almucantar mirror symmetry about the meridian
            left, right = _cie_enu(model, [Z, Z], [azs - dpsi, azs + dpsi], Zs, azs)
            assert left == pytest.approx(right, rel=1e-6)
    for sky_type in (7, 8, 10, 11, 12, 13, 14, 15):  # clear/corona skies: brighter towards the sun
        m = CIEStandardSky(sky_type)
        for Z in (20.0, 70.0):
            sun_side, anti_side = _cie_enu(m, [Z, Z], [azs, azs + 180.0], Zs, azs)
            assert sun_side > anti_side
    uniform = CIEStandardSky(5)  # type 5: uniform luminance
    np.testing.assert_allclose(
        _cie_enu(uniform, [0.0, 40.0, 89.0], [0.0, 200.0, 20.0], 30.0, 0.0), 1.0, atol=2e-6
    )


def test_cie_below_horizon_is_finite_and_continuous():
    for sky_type in (1, 12, 15):
        m = CIEStandardSky(sky_type)
        L = _cie_enu(m, [89.99, 90.01, 120.0, 180.0], [10.0, 10.0, 10.0, 10.0], 40.0, 0.0)
        assert np.isfinite(L).all() and (L > 0).all()
        assert L[0] == pytest.approx(L[1], rel=1e-3)
    # custom sky with b = 0: gradation constant 1 + a everywhere, also below the horizon
    flat = make_radiance_model(
        {'model': 'cie_standard', 'a': 2.0, 'b': 0.0, 'c': 0.0, 'd': -1.0, 'e': 0.0}
    )
    np.testing.assert_allclose(
        _cie_enu(flat, [10.0, 89.9, 95.0], [0.0, 0.0, 0.0], 30.0, 0.0), 1.0, atol=2e-6
    )


@pytest.mark.parametrize(
    'cfg',
    [
        {'model': 'perez'},
        {'model': 'cie_clear', 'type': 0},
        {'model': 'cie_clear', 'type': 16},
        {'model': 'cie_clear', 'type': 12.5},
        {'model': 'cie_clear', 'type': True},
        {'model': 'cie_clear', 'type': '12'},
        {'model': 'cie_clear', 'turbidity': 3},
        {'model': 'cie_standard', 'a': 1.0, 'b': -0.5},
        {'model': 'cie_standard', 'a': -1, 'b': 0.5, 'c': 10, 'd': -3, 'e': 0.45},
        {'model': 'cie_standard', 'a': -1, 'b': -0.32, 'c': -10, 'd': -3, 'e': 0.45},
        {'model': 'cie_standard', 'a': -2, 'b': -0.32, 'c': 10, 'd': -3, 'e': 0.45},
        {'model': 'cie_standard', 'a': 'x', 'b': -0.32, 'c': 10, 'd': -3, 'e': 0.45},
        {'model': 'cie_clear', 'type': 12, 'a': -1, 'b': -0.32, 'c': 10, 'd': -3, 'e': 0.45},
        'cie_clear',
    ],
)
def test_cie_rejects_bad_config(cfg):
    with pytest.raises(RadianceError):
        make_radiance_model(cfg)


@given(
    sun_az=st.floats(0, 360),
    sun_alt=st.floats(-10, 90),
    bearing=st.floats(0, 360),
    pitch=st.floats(-80, 80),
    roll=st.floats(-80, 80),
    sky_type=st.integers(1, 15),
)
def test_cie_outputs_always_finite_positive(sun_az, sun_alt, bearing, pitch, roll, sky_type):
    _, s_cam, z_cam = _camera(bearing, pitch, roll, sun_az, sun_alt)
    L = CIEStandardSky(sky_type).radiance(s_cam, z_cam, _GRID)
    assert L.dtype == np.float32 and L.shape == (_GRID.shape[1],)
    assert np.isfinite(L).all() and (L > 0).all()


# ---------------------------------------------------------------------------------------------
# Scenes and the renderer
# ---------------------------------------------------------------------------------------------
def test_scene_files_load_and_render():
    bdl = load_scene(SCENES / 'bdl_sky.yaml')
    assert bdl.sky == {'model': 'berry_dennis_lee', 'separation_deg': 18.0, 'dop_max': 0.75}
    cie = load_scene(SCENES / 'cie_clear_radiance.yaml')
    assert cie.radiance == {'model': 'cie_clear', 'type': 12}
    att, sun = CameraAttitude(40.0, -10.0, 5.0), SunDirection(150.0, 35.0)
    fb = Renderer(bdl, pixels=PixelSelection.grid(48, 40)).render(attitude=att, sun=sun)
    assert fb.meta['sky'] == {'model': 'berry_dennis_lee', 'separation_deg': 18.0, 'dop_max': 0.75}
    assert fb.intensity is None and 0.5 < float(fb.dop.max()) <= 0.75
    fc = Renderer(cie, pixels=PixelSelection.grid(48, 40)).render(attitude=att, sun=sun)
    assert fc.intensity is not None and fc.intensity.shape == fc.aop_rad.shape
    assert fc.meta['radiance']['type'] == 12
    # independent: the hand formula at each pixel's (zenith angle, azimuth)
    R = R_enu_cam_from_attitude(40.0, -10.0, 5.0)
    P = R @ fc.rays_cam.astype(float)
    Z = np.degrees(np.arccos(np.clip(P[2], -1, 1)))
    az = np.degrees(np.arctan2(P[0], P[1]))
    up = Z < 89.0
    np.testing.assert_allclose(
        fc.intensity.reshape(-1)[up], cie_by_hand(12, Z[up], az[up], 55.0, 150.0), rtol=3e-5
    )


def test_scene_with_bad_models_is_a_scene_error():
    with pytest.raises(SceneError, match='sky'):
        scene_from_dict({'sky': {'model': 'berry_dennis_lee', 'separation_deg': 90}})
    with pytest.raises(SceneError, match='radiance'):
        scene_from_dict({'radiance': {'model': 'cie_clear', 'type': 99}})


def _imported_modules(path: Path) -> set[str]:
    """
    Return every module a source file imports, read with ast.

    At module level or inside a function, relative names resolved against the package: the import
    graph, not what happens to be loaded.
    """
    import ast

    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = '.'.join(
                p for p in ('polarization_compass' if node.level else '', node.module or '') if p
            )
            out.add(base)
            out.update(f'{base}.{a.name}' for a in node.names)
    return out


def test_sky_model_modules_import_downwards_only():
    """
    Sky model modules import downwards only.

    sky <- sky_bdl <- sky_models: no model module imports the registry or another model upwards
    (sky used to import sky_bdl inside make_sky_model to register it, a cycle).
    """
    pkg = Path(__file__).resolve().parents[1] / 'polarization_compass'
    sky, bdl = _imported_modules(pkg / 'sky.py'), _imported_modules(pkg / 'sky_bdl.py')
    assert not {
        m
        for m in sky
        if m.startswith(('polarization_compass.sky_bdl', 'polarization_compass.sky_models'))
    }
    assert not {m for m in bdl if m.startswith('polarization_compass.sky_models')}
    assert 'polarization_compass.sky' in bdl


def test_a_registered_sky_model_is_built_by_name():
    from polarization_compass.sky_models import _REGISTRY, register_sky_model, sky_model_names

    try:

        @register_sky_model('toy_sky')
        class Toy:
            """A sky model made up for the test."""

            def __init__(self, k=1):
                self.k = k

        assert 'toy_sky' in sky_model_names() and {'rayleigh', 'berry_dennis_lee'} <= set(
            sky_model_names()
        )
        assert make_sky_model({'model': 'toy_sky', 'k': 3}).k == 3
        with pytest.raises(SkyModelError, match='bad parameters'):
            make_sky_model({'model': 'toy_sky', 'q': 3})
    finally:
        _REGISTRY.pop('toy_sky', None)
    with pytest.raises(SkyModelError, match="unknown sky model 'toy_sky'"):
        make_sky_model({'model': 'toy_sky'})
