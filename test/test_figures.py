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
Figures from a closed-form map draw the map's numbers with labelled axes.

Figures from a map built from the closed-form level-assumption error (no sweep needed): every
figure draws, labels its axes with units, plots the map's numbers (not something else), blanks
invalid cells, and the CLI writes PNGs.
"""

import json
import subprocess
import sys

import numpy as np
from polarization_compass import conventions as cv
from polarization_compass.errormap import ErrorMap, ErrorMapError, tilt_domain_mask
from polarization_compass.figures import draw_figure, FIGURES, save_all
import pytest
from test_errormap import level_assumption_error_deg

METHODS = ('zenith', 'sm_asm', 'symmetry', 'least_squares')
OFFSETS = (0.0, 0.1, -0.1, 0.05)  # tells the methods' curves apart


def closed_form_map():
    alt = np.arange(0.0, 51.0, 10.0)
    yaw = np.arange(-180.0, 180.1, 10.0)
    tilt = np.arange(-30.0, 30.1, 10.0)
    h, y, p, r = np.meshgrid(alt, yaw, tilt, tilt, indexing='ij')
    base = level_assumption_error_deg(y, h, p, r)
    e = np.stack([cv.fold_axial_deg(base + o) for o in OFFSETS])
    st = np.zeros(e.shape, np.int8)
    st[..., ~tilt_domain_mask(tilt, tilt, 30.0, 2)] = -1
    st[2, 3, 5, 1, 3] = 7  # one failed estimate: symmetry, h 30, yaw -130, pitch -20, roll 0
    e = np.where(st == 0, e, 0.0)
    return ErrorMap(
        e,
        st,
        METHODS,
        alt,
        yaw,
        tilt,
        tilt,
        {'domain': {'tilt_limit_deg': 30.0, 'full_domain': False}},
    )


@pytest.fixture(scope='module')
def cmap():
    return closed_form_map()


def _labels(fig):
    out = []
    for ax in fig.axes:
        for get in ('get_xlabel', 'get_ylabel', 'get_zlabel'):
            if hasattr(ax, get) and getattr(ax, get)():
                out.append(getattr(ax, get)())
    return out


@pytest.fixture(scope='module')
def drawn(cmap):
    import matplotlib.pyplot as plt

    figs = {name: draw_figure(cmap, name) for name in FIGURES}
    yield figs
    for f in figs.values():
        plt.close(f)


@pytest.mark.parametrize('name', list(FIGURES))
def test_every_figure_draws_with_labelled_axes(drawn, name, tmp_path):
    import matplotlib.image as mpimg

    fig = drawn[name]
    labels = _labels(fig)
    assert labels and all('(deg)' in lab for lab in labels), labels
    assert any('yaw' in lab for lab in labels) or name == 'fig14'
    fig.savefig(tmp_path / 'f.png')
    img = mpimg.imread(tmp_path / 'f.png')
    assert img.shape[0] >= 500 and img.shape[1] >= 700
    assert img[..., :3].std() > 0.05  # not blank


def test_fig8_curves_are_the_map_values(cmap):
    import matplotlib.pyplot as plt

    fig = draw_figure(cmap, 'fig8', pitch=-20.0)
    ax = fig.axes[0]
    lines = [ln for ln in ax.get_lines() if len(ln.get_xdata()) == cmap.yaw_deg.size]
    assert len(lines) == cmap.sun_altitude_deg.size * len(METHODS)
    ref = level_assumption_error_deg(cmap.yaw_deg, 50.0, -20.0, 0.0)  # last altitude, zenith (+0)
    got = [np.asarray(ln.get_ydata(), dtype=float) for ln in lines]
    assert min(np.abs(g - ref).max() for g in got) < 1e-9
    plt.close(fig)


def test_invalid_cells_are_blank_not_zero(cmap):
    import matplotlib.pyplot as plt

    fig = draw_figure(cmap, 'fig9', pitch=-20.0, sun_altitude=30.0)
    ax = fig.axes[0]
    sym = [ln for ln in ax.get_lines() if ln.get_label() == 'Symmetry'][0]
    y = sym.get_ydata()
    assert np.ma.is_masked(y) and bool(np.ma.getmaskarray(y)[5])
    plt.close(fig)


def test_fig13_overlays_the_pitch_curve_shifted_by_90_deg(cmap):
    import matplotlib.pyplot as plt

    fig = draw_figure(cmap, 'fig13', roll=-20.0, sun_altitude=50.0)
    ax = fig.axes[0]
    dots = [ln for ln in ax.get_lines() if 'Only pitch' in ln.get_label()][0]
    x, y = np.asarray(dots.get_xdata(), float), np.asarray(dots.get_ydata(), float)
    # eq 32, independently: roll-only error at yaw x equals the closed-form roll-only error
    ref = level_assumption_error_deg(x, 50.0, 0.0, -20.0) + OFFSETS[-1]
    assert np.abs(cv.fold_axial_deg(y - ref)).max() < 1e-6
    plt.close(fig)


def test_figures_refuse_maps_without_what_they_need(cmap):
    one_roll = ErrorMap(
        cmap.error_deg[..., :1],
        cmap.status[..., :1],
        cmap.methods,
        cmap.sun_altitude_deg,
        cmap.yaw_deg,
        cmap.pitch_deg,
        cmap.roll_deg[:1],
        cmap.meta,
    )  # roll = -30 only
    for name in ('fig7', 'fig8', 'fig14'):
        with pytest.raises(ErrorMapError):
            draw_figure(one_roll, name)
    with pytest.raises(ErrorMapError, match='not a node'):
        draw_figure(cmap, 'fig8', pitch=-25.0)
    with pytest.raises(ErrorMapError, match='unknown figure'):
        draw_figure(cmap, 'fig99')


def test_save_all_writes_every_figure(cmap, tmp_path):
    small = ErrorMap(
        cmap.error_deg[:1, ::2],
        cmap.status[:1, ::2],
        cmap.methods[:1],
        cmap.sun_altitude_deg[::2],
        cmap.yaw_deg,
        cmap.pitch_deg,
        cmap.roll_deg,
        cmap.meta,
    )
    paths = save_all(small, tmp_path)
    assert [p.name for p in paths] == [f'{n}.png' for n in FIGURES]
    assert all(p.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' for p in paths)


def test_plot_cli(cmap, tmp_path):
    path = cmap.save(tmp_path / 'm.npz')
    base = [sys.executable, '-m', 'polarization_compass.cli', 'plot', str(path)]
    r = subprocess.run(
        base + ['--figure', 'fig14', '--out', str(tmp_path / 'f14.png'), '--sun-altitude', '40'],
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)['written'] == [str(tmp_path / 'f14.png')]
    assert (tmp_path / 'f14.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    for bad in (
        ['--figure', 'fig99', '--out', str(tmp_path / 'x.png')],
        ['--figure', 'fig7', '--out', str(tmp_path / 'x.jpg')],
        ['--figure', 'fig8', '--out', str(tmp_path / 'x.png'), '--pitch', '-25'],
    ):
        r = subprocess.run(base + bad, capture_output=True, text=True, timeout=180)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, (bad, r.stderr)
