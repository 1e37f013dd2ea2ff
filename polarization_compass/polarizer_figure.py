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
The picture of ``check-polarizer --plot``: every polarizer hypothesis side by side (issue 25).

One row per input, one column per hypothesis (:func:`polarization_compass.polarizer_check.
polarizer_hypotheses`: the configured one first); each panel is the AoP under that hypothesis minus
the single-scattering sky fitted to it (the psi and sun altitude the check found), so the right
convention is the nearly white panel. Titles give the hypothesis, its mean robust loss and whether
it is the configured or the best one; the figure's title the verdict and the fix.
"""

from __future__ import annotations

import numpy as np

__all__ = ['save_polarizer_figure']

#: longest side of each panel [cells]
PANEL_SIDE = 160


def save_polarizer_figure(
    report: dict,
    paths,
    camera_yaml,
    out_path,
    bits=None,
    mask_path=None,
    pitch_deg: float = 0.0,
    roll_deg: float = 0.0,
) -> None:
    """
    Write the hypotheses' residual maps of a polarizer check as a PNG.

    Parameters
    ----------
    report : dict
        :func:`polarization_compass.polarizer_files.check_polarizer_files`'s report.
    paths : sequence of str
        The inputs it was run on.
    camera_yaml : str
        The camera file.
    out_path : str
        The PNG to write.
    bits : int, optional
        Significant bits of a raw mosaic in a 16-bit container.
    mask_path : str, optional
        Static mask (non-zero = sky).
    pitch_deg, roll_deg : float, default 0
        Camera tilt [deg] the check used.

    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from .camera import load_camera_yaml
    from .polarizer_check import polarizer_hypotheses
    from .polarizer_files import _masks, _read_inputs

    cf = load_camera_yaml(camera_yaml)
    inputs, shapes = _read_inputs(paths, bits, cf.camera.shape)
    masks = _masks(mask_path, inputs, shapes, cf.camera.shape) if mask_path else None
    raw = all(k == 'mosaic' for k, _, _ in inputs)
    hyps = polarizer_hypotheses(cf.layout, cf.pol45_toward, raw)
    rows = {_key(r['hypothesis']): r for r in report['hypotheses']}
    n, m = len(inputs), len(hyps)
    width_in = max(2.6 * m + 0.8, 7.0)
    title = _verdict(report, int(width_in * 13))
    head_in = 0.2 * (title.count('\n') + 1) + 0.5
    fig = Figure(figsize=(width_in, 2.5 * n + head_in + 0.2), dpi=100)
    FigureCanvasAgg(fig)
    im = None
    for i, inp in enumerate(inputs):
        mask = None if masks is None else masks[i]
        for j, h in enumerate(hyps):
            ax = fig.add_subplot(n, m, i * m + j + 1)
            row = rows.get(_key(h.describe()), {})
            frame = row.get('frames', [{}])[i]
            res = _residual(cf.camera, inp, h, frame, mask, pitch_deg, roll_deg)
            im = _panel(ax, res, _panel_title(h, row, i, report, j == 0)) or im
            if j == 0:
                ax.set_ylabel(str(paths[i]).rsplit('/', 1)[-1], fontsize=7)
    if im is not None:
        cb = fig.colorbar(im, cax=fig.add_axes([0.89, 0.1, 0.02, 0.6]))
        cb.set_label('AoP minus fitted sky [deg]', fontsize=8)
    fig.subplots_adjust(left=0.04, right=0.86, bottom=0.03, top=1 - head_in / fig.get_figheight())
    fig.suptitle(title, fontsize=8)
    fig.savefig(out_path, format='png')


def _panel(ax, res, title: str):
    """Draw one residual map (or nothing) with its title; return the image or None."""
    im = None
    if res is not None:
        im = ax.imshow(res, cmap='coolwarm', vmin=-30, vmax=30, interpolation='nearest')
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title, fontsize=7)
    return im


def _residual(camera, inp, hyp, frame: dict, mask, pitch_deg, roll_deg):
    """Return one input's residual map under one hypothesis, downscaled; None without a fit."""
    from .polarizer_check import _aop_for
    from .polarizer_files import plane_rays
    from .sky_view import aop_residual_deg
    from .skyfit import data_mask

    if 'psi_deg' not in frame:
        return None
    kind, data, sat = inp
    a, d, v, s0 = _aop_for(kind, data, hyp, sat)
    _, _, rays, has_ray = plane_rays(camera, a.shape)
    keep = data_mask(
        s0, np.asarray(has_ray).reshape(a.shape), float('inf') if kind == 'mosaic' else None
    )
    if mask is not None:
        keep &= mask
    step = max(1, -(-max(a.shape) // PANEL_SIDE))
    sl = (slice(step // 2, None, step), slice(step // 2, None, step))
    r = np.asarray(rays).reshape((3,) + a.shape)[(slice(None),) + sl]
    return aop_residual_deg(
        a[sl],
        r.reshape(3, -1),
        (v & keep)[sl],
        frame['psi_deg'],
        frame['sun_altitude_deg'],
        pitch_deg,
        roll_deg,
    )


def _key(described: dict) -> str:
    import json

    return json.dumps(described, sort_keys=True)


def _name(described: dict) -> str:
    rows = '/'.join(','.join(f'{a:g}' for a in r) for r in described['layout'])
    return f'layout {rows}, 45 deg toward {described["pol45_toward"]}'


def _panel_title(hyp, row: dict, i: int, report: dict, configured: bool) -> str:
    best_name = report.get('best')
    tags = [
        t for t, on in (('configured', configured), ('best', hyp.describe() == best_name)) if on
    ]
    frames = row.get('frames') or [{}]
    loss = frames[i].get('loss') if i < len(frames) else None
    mean = row.get('loss')
    loss_txt = 'too few pixels' if loss is None else f'loss {loss:.3f}'
    if loss is not None and mean is not None and len(frames) > 1:
        loss_txt += f' (mean {mean:.3f})'
    return f'{_name(hyp.describe())}\n{loss_txt}' + (f' {", ".join(tags)}' if tags else '')


def _verdict(report: dict, width: int) -> str:
    import textwrap

    lines = textwrap.wrap(
        f'polarizer check: {report.get("verdict")} -- {report.get("reason", "")}', width
    )
    if report.get('fix'):
        lines += textwrap.wrap(f'fix: {report["fix"]}', width)
    return '\n'.join(lines[:6])
