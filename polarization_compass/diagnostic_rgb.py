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
The diagnostic figure's layers drawn straight into an RGB array, fast (issue 25).

For every frame of a replay (``replay --plots-every``) and the node's ``~/debug_image``, where
matplotlib's figure (:mod:`polarization_compass.diagnostic_figure`, ~1 s) is too slow: numpy
colour look-ups and OpenCV drawing, a few ms. Four panels of a
:class:`polarization_compass.sky_view.SkyView` -- AoP (twilight) with the solar meridian, the
fitted sun and each method's sun azimuth; the pixels used and masked (the figure's colours); the
residual against the fitted sky (coolwarm, +-30 deg); the DoP (viridis) -- under two lines of
status, over a legend of the classes with their counts. :func:`panel_origin_px` says where a
panel lies, so a test can read a pixel back.
"""

from __future__ import annotations

import numpy as np

from .diagnostic_figure import CLASS_COLOURS
from .sky_view import CLASSES

__all__ = ['PANELS', 'panel_origin_px', 'quick_rgb']

#: panel names, row-major in the 2 x 2 grid
PANELS = ('aop', 'classes', 'residual', 'dop')
_HEAD_PX = 34
_LEGEND_ROW_PX = 14
_LUTS: dict = {}


def _lut(name: str) -> np.ndarray:
    if name not in _LUTS:
        from matplotlib import colormaps

        _LUTS[name] = (colormaps[name](np.linspace(0, 1, 256))[:, :3] * 255).astype(np.uint8)
    return _LUTS[name]


def _coloured(values, lo, hi, cmap) -> np.ndarray:
    """Map values in [lo, hi] through a colour map; NaN white."""
    v = np.asarray(values, np.float32)
    ok = np.isfinite(v)
    idx = np.zeros(v.shape, np.int64)
    idx[ok] = np.clip((v[ok] - lo) / (hi - lo) * 255.0 + 0.5, 0, 255).astype(np.int64)
    out = _lut(cmap)[idx]
    out[~ok] = 255
    return out


def panel_size_px(view, width_px: int) -> tuple:
    """Return (width, height) [px] of one panel in a picture ``width_px`` wide."""
    h, w = view.classes.shape
    pw = max(8, width_px // 2)
    return pw, max(8, int(round(pw * h / w)))


def panel_origin_px(view, width_px: int, name: str) -> tuple:
    """Return the (column, row) [px] of a panel's top-left corner in :func:`quick_rgb`."""
    pw, ph = panel_size_px(view, width_px)
    k = PANELS.index(name)
    return (k % 2) * pw, _HEAD_PX + (k // 2) * ph


def to_panel_px(view, width_px: int, x_px, y_px) -> tuple:
    """Map 1-based sensor (x, y) [px] to (column, row) [px] inside a panel."""
    pw, ph = panel_size_px(view, width_px)
    x0, x1, y1, y0 = view.extent
    return (x_px - x0) / (x1 - x0) * pw, (y_px - y0) / (y1 - y0) * ph


def quick_rgb(view, width_px: int = 640) -> np.ndarray:
    """
    Draw a view's layers into an RGB picture (see the module docstring).

    Parameters
    ----------
    view : SkyView
        The layers (:mod:`polarization_compass.sky_view`).
    width_px : int, default 640
        Width of the picture [px].

    Returns
    -------
    numpy.ndarray
        uint8, shape (height, width_px, 3), C-contiguous.

    """
    import cv2

    pw, ph = panel_size_px(view, width_px)
    rows = [i for i, n in enumerate(view.counts) if n or i == 0]
    height = _HEAD_PX + 2 * ph + _LEGEND_ROW_PX * ((len(rows) + 1) // 2) + 4
    img = np.full((height, 2 * pw, 3), 255, np.uint8)
    res = (
        view.residual_deg if view.residual_deg is not None else np.full(view.classes.shape, np.nan)
    )
    layers = {
        'aop': _coloured(view.aop_deg, -90.0, 90.0, 'twilight'),
        'classes': (np.asarray(CLASS_COLOURS) * 255).astype(np.uint8)[view.classes],
        'residual': _coloured(res, -30.0, 30.0, 'coolwarm'),
        'dop': _coloured(view.dop, 0.0, 1.0, 'viridis'),
    }
    for name, layer in layers.items():
        c, r = panel_origin_px(view, width_px, name)
        img[r : r + ph, c : c + pw] = cv2.resize(layer, (pw, ph), interpolation=cv2.INTER_NEAREST)
        _overlay(img, view, width_px, name)
    _header(img, view)
    _legend(img, view, rows, _HEAD_PX + 2 * ph + 2, pw)
    return np.ascontiguousarray(img)


def _overlay(img, view, width_px, name) -> None:
    """Draw the meridian and the fitted sun on a panel; the methods' sun arrows on the AoP."""
    import cv2

    c0, r0 = panel_origin_px(view, width_px, name)
    pw, ph = panel_size_px(view, width_px)
    sub = img[r0 : r0 + ph, c0 : c0 + pw]
    if view.meridian_px is not None:
        x, y = to_panel_px(view, width_px, *view.meridian_px)
        half = x.size // 2
        for part, colour in (
            (slice(0, half + 1), (255, 200, 0)),
            (slice(half, None), (255, 255, 255)),
        ):
            pts = np.stack([x[part], y[part]], axis=1)
            pts = pts[np.isfinite(pts).all(axis=1)]
            if len(pts) > 1:
                cv2.polylines(sub, [np.rint(pts).astype(np.int32)], False, colour, 1, cv2.LINE_AA)
    if view.sun_px is not None:
        sx, sy = to_panel_px(view, width_px, *view.sun_px)
        cv2.circle(sub, (int(round(sx)), int(round(sy))), 5, (255, 200, 0), -1, cv2.LINE_AA)
        cv2.circle(sub, (int(round(sx)), int(round(sy))), 5, (0, 0, 0), 1, cv2.LINE_AA)
    if name != 'aop':
        return
    cx, cy = to_panel_px(view, width_px, *view.centre_px)
    length = 0.4 * min(pw, ph)
    for i, r in enumerate(view.results):
        d = view.sun_dir_img.get(r.method)
        if d is None:
            continue
        colour = _METHOD_RGB[i % len(_METHOD_RGB)]
        tip = (int(round(cx + length * d[0])), int(round(cy + length * d[1])))
        cv2.arrowedLine(
            sub, (int(round(cx)), int(round(cy))), tip, colour, 2, cv2.LINE_AA, tipLength=0.15
        )


_METHOD_RGB = ((214, 39, 40), (31, 119, 180), (44, 160, 44), (148, 103, 189), (140, 86, 75))


def _header(img, view) -> None:
    """Two lines: what the image is and the best result; each method's status and bearing."""
    import cv2

    fit = view.fit
    first = view.label or 'image'
    if fit is not None:
        sig = '' if fit.sigma_deg is None else f' +- {fit.sigma_deg:.2g}'
        b = '--' if fit.bearing_deg is None else f'{fit.bearing_deg:.1f}'
        first += f' | fit: {fit.method} {fit.status.value}, bearing {b}{sig} deg'
    second = '; '.join(
        f'{r.method} {r.status.value}' + ('' if r.bearing_deg is None else f' {r.bearing_deg:.1f}')
        for r in view.results
    )
    if len(view.results) == 1:
        second = view.results[0].reason or second
    for k, text in enumerate((first, second)):
        cv2.putText(
            img,
            text[:110],
            (4, 13 + 15 * k),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.36,
            (0, 0, 0),
            1,
            cv2.LINE_AA,
        )


def _legend(img, view, rows, top, col_px) -> None:
    """Colour swatch, class and full-resolution count, two columns."""
    import cv2

    for k, i in enumerate(rows):
        x, y = (k % 2) * col_px + 4, top + (k // 2) * _LEGEND_ROW_PX
        colour = tuple(int(round(255 * c)) for c in CLASS_COLOURS[i])
        cv2.rectangle(img, (x, y + 2), (x + 10, y + 11), colour, -1)
        cv2.rectangle(img, (x, y + 2), (x + 10, y + 11), (0, 0, 0), 1)
        text = f'{CLASSES[i]}: {view.counts[i]}'
        if view.counted_every_px > 1 and k == 0:
            text += f' (every {view.counted_every_px}th px)'
        cv2.putText(
            img,
            text[: max(10, col_px // 5)],
            (x + 14, y + 11),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.3,
            (0, 0, 0),
            1,
            cv2.LINE_AA,
        )
