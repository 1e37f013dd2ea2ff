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
Which polarizer convention does the sky support? A check that needs no calibration rig.

A wrong +45 deg direction mirrors every AoP about the image x axis; a wrong 2 x 2 phase of a raw
mosaic swaps polarizer channels (AoP rotated by 45 or 90 deg, or mirrored and rotated). Neither
image is a single-scattering sky for *any* sun except in special geometries, so fitting the
Rayleigh pattern (:func:`polarization_compass.skyfit.fit_sky`, sun azimuth and altitude free unless
the altitude is given) under each hypothesis and comparing the robust losses tells which convention
the sky supports, and by what margin. Losses of several frames add up (one camera, one convention).

Hypotheses: for Stokes planes both 45 deg directions; for a raw mosaic the four 2 x 2 phases of the
configured layout times both directions (eight). The verdict is ``supported`` (the configuration is
the best and beats the runner-up by at least :data:`DECISIVE_MARGIN` in mean Cauchy loss per
frame), ``contradicted`` (another hypothesis wins by that margin: the report says what to set), or
``cannot_tell`` (the margin is smaller: e.g. a sun near an image axis or the zenith, an overcast
sky).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .demosaic import aop_dop_from_stokes, parse_layout, stokes_from_mosaic
from .errors import CompassError
from .skyfit import data_mask, fit_sky, sample_sky

__all__ = [
    'Hypothesis',
    'polarizer_hypotheses',
    'check_polarizer',
    'saturated_blocks',
    'decimated_blocks',
    'check_frame',
    'gate_result',
    'disfavoured',
    'contradiction_text',
    'FRAME_CHECK_MAX_SAMPLES',
    'GATE_MARGIN',
    'DECISIVE_MARGIN',
]

#: mean Cauchy-loss difference per frame between the best and the runner-up needed for a verdict.
#: Measured: real clear sky 1.18, real broken cloud 0.24, real overcast 0.22, clean simulated skies
#: > 1.
DECISIVE_MARGIN = 0.1

#: mean Cauchy-loss deficit of the configured convention behind the best hypothesis from which a
#: heading is refused even when the verdict is ``cannot_tell`` (:func:`gate_result`): a sun near
#: the horizon mirrors into a nearly valid sky (simulated +x+y sensor, +x-y configuration, sun
#: at 2 deg: deficit 0.047, margin below :data:`DECISIVE_MARGIN`, headings 120-160 deg off); the
#: right convention is the best hypothesis on every simulated and real frame (deficit 0).
GATE_MARGIN = 0.02

#: most 2 x 2 blocks (raw mosaic) or Stokes pixels the per-frame check (:func:`check_frame`) fits.
#: Measured on the real ``sunny`` frame (2048 x 2048 Stokes, one core, loaded machine): the whole
#: frame 2.6 s, every 4th pixel (262 k) 107 ms, every 8th 64 ms, all with the same verdict and
#: margin within 0.03.
FRAME_CHECK_MAX_SAMPLES = 10000


@dataclass(frozen=True)
class Hypothesis:
    """
    A polarizer convention: ``layout`` and ``pol45_toward``.

    ``layout`` holds the 2 x 2 angles of the image's top-left block.
    """

    layout: tuple
    pol45_toward: str

    def describe(self) -> dict:
        """
        Return the hypothesis as JSON-ready data.

        Returns
        -------
        dict
            ``{"layout": [[a00, a01], [a10, a11]], "pol45_toward": "+x+y" or "+x-y"}`` with the
            polarizer angles of the top-left 2 x 2 block [deg].

        """
        return {'layout': [list(r) for r in self.layout], 'pol45_toward': self.pol45_toward}


def polarizer_hypotheses(layout, pol45_toward: str, raw: bool) -> list[Hypothesis]:
    """
    List the configured polarizer convention first, then the alternatives.

    Both 45 deg directions; for a raw mosaic also the four 2 x 2 phases of the layout (eight
    hypotheses), for Stokes planes only the configured phase (two).

    Parameters
    ----------
    layout : array_like of shape (2, 2) or MosaicLayout
        Configured 2 x 2 polarizer angles of the top-left block [deg], in any form that
        :func:`polarization_compass.demosaic.parse_layout` accepts.
    pol45_toward : str
        Configured direction of the +45 deg polarizer, ``"+x+y"`` or ``"+x-y"`` (image axes).
    raw : bool
        True when the inputs are raw mosaics (all four phases are hypotheses).

    Returns
    -------
    list of Hypothesis
        The configured convention first, then the alternatives.

    """
    base = parse_layout(layout, pol45_toward)
    other = '+x+y' if base.pol45_toward == '+x-y' else '+x-y'
    out = []
    phases = [(0, 0), (0, 1), (1, 0), (1, 1)] if raw else [(0, 0)]
    for pol in (base.pol45_toward, other):
        for dy, dx in phases:
            out.append(Hypothesis(base.shifted(dy, dx).angles_deg, pol))
    return out


def saturated_blocks(mosaic, saturation_level, shape) -> np.ndarray:
    """
    Mark where a raw sample is saturated, at the resolution ``shape``.

    At the mosaic's own resolution each sample counts; at one value per 2 x 2 superpixel any
    saturated sample saturates the block.

    Parameters
    ----------
    mosaic : array_like, shape (H, W)
        Raw polarization mosaic (sensor counts).
    saturation_level : float or None
        Count at and above which a sample is saturated; None: nothing is saturated.
    shape : tuple of int
        Output shape: ``(H, W)`` or the superpixel grid ``(H // 2, W // 2)``.

    Returns
    -------
    numpy.ndarray of bool
        True where saturated, of shape ``shape``.

    """
    m = np.asarray(mosaic)
    if saturation_level is None:
        return np.zeros(shape, bool)
    sat = m >= saturation_level
    if sat.shape == tuple(shape):
        return sat
    h, w = shape
    return sat[: 2 * h, : 2 * w].reshape(h, 2, w, 2).any(axis=(1, 3))


def decimated_blocks(mosaic: np.ndarray, max_blocks: int):
    """
    Keep every k-th 2 x 2 block of a mosaic, as one smaller mosaic with the same 2 x 2 phase.

    Parameters
    ----------
    mosaic : numpy.ndarray
        Raw DoFP image (H, W).
    max_blocks : int
        At most this many blocks are kept (k the smallest step that achieves it).

    Returns
    -------
    tuple
        ``(small, k, nx, ny)``: the (2 ny, 2 nx) mosaic whose block (j, i) is centred at 1-based
        sensor pixel ``(1.5 + 2 k i, 1.5 + 2 k j)``, the step k and the block counts.

    """
    H, W = mosaic.shape
    by, bx = H // 2, W // 2
    k = max(1, int(math.ceil(math.sqrt(by * bx / max(int(max_blocks), 1)))))
    ny, nx = (by + k - 1) // k, (bx + k - 1) // k
    blocks = mosaic[: 2 * by, : 2 * bx].reshape(by, 2, bx, 2)[::k, :, ::k, :]
    return np.ascontiguousarray(blocks).reshape(2 * ny, 2 * nx), k, nx, ny


def _aop_for(kind: str, data, hyp: Hypothesis, saturation_level):
    """
    Return (aop, dop, valid, s0) of one input under one hypothesis.

    A mosaic is read at superpixel resolution.
    """
    if kind == 'mosaic':
        s0, s1, s2 = stokes_from_mosaic(
            data, hyp.layout, hyp.pol45_toward, 'superpixel', saturation_level
        )
        s0 = np.where(saturated_blocks(data, saturation_level, s0.shape), np.float32(np.inf), s0)
    else:
        s0, s1, s2 = data
        if hyp.pol45_toward == '+x-y':  # SDK Stokes use the sensor's labels: camera S2 flips
            s2 = -s2
    a, d, v = aop_dop_from_stokes(s0, s1, s2)
    return a, d, v, s0


def check_polarizer(
    inputs,
    camera,
    layout,
    pol45_toward,
    rays_for_shape,
    sun_altitude_deg=None,
    pitch_deg: float = 0.0,
    roll_deg: float = 0.0,
    masks=None,
) -> dict:
    """
    Fit every polarizer hypothesis to every input and rank them.

    Each hypothesis gives each input an AoP image; :func:`~polarization_compass.skyfit.fit_sky`
    fits the single-scattering pattern (seed paper eqs 18 and 28) to it and the mean robust loss
    per frame ranks the hypotheses. The verdict is ``supported``, ``contradicted`` or
    ``cannot_tell`` by :data:`DECISIVE_MARGIN` (module docstring).

    Parameters
    ----------
    inputs : list of tuple
        ``(kind, data, saturation_level)`` per frame: kind ``"mosaic"`` with a 2-D raw image, or
        ``"stokes"`` with ``(S0, S1, S2)`` in the camera SDK's convention; saturation level in
        sensor counts or None.
    camera : CameraModel
        The lens model of the frames (the pixel rays themselves come from ``rays_for_shape``).
    layout : array_like of shape (2, 2) or MosaicLayout
        Configured 2 x 2 polarizer angles [deg] (:func:`polarizer_hypotheses`).
    pol45_toward : str
        Configured direction of the +45 deg polarizer, ``"+x+y"`` or ``"+x-y"``.
    rays_for_shape : callable
        ``rays_for_shape(shape) -> (rays, has_ray)``: unit camera-frame rays (3, N) of an output
        grid and a bool mask of the pixels inside the lens' field.
    sun_altitude_deg : float or list of float, optional
        Sun altitude [deg], one for all inputs or one per input; None fits it.
    pitch_deg : float, default 0
        Camera pitch [deg].
    roll_deg : float, default 0
        Camera roll [deg].
    masks : list of (numpy.ndarray of bool or None), optional
        Per-input masks of the output grid (True = sky).

    Returns
    -------
    dict
        JSON-ready: ``verdict``, ``reason``, ``best``, ``configured``, ``margin`` (mean Cauchy
        loss per frame), ``frames`` (count), ``hypotheses`` (each with its mean loss, None when a
        frame had too few pixels, and per-frame psi [deg], sun altitude [deg], loss, scatter [deg],
        inlier fraction), and ``fix`` (the setting to use) when contradicted.

    Raises
    ------
    CompassError
        When ``inputs`` is empty.

    """
    if not inputs:
        raise CompassError('check-polarizer needs at least one input')
    raw = all(k == 'mosaic' for k, _, _ in inputs)
    hyps = polarizer_hypotheses(layout, pol45_toward, raw)
    alts = (
        sun_altitude_deg
        if isinstance(sun_altitude_deg, (list, tuple))
        else [sun_altitude_deg] * len(inputs)
    )
    rows = [
        _fit_hypothesis(h, inputs, alts, rays_for_shape, masks, pitch_deg, roll_deg) for h in hyps
    ]
    return _rank(rows, hyps[0], len(inputs))


def check_frame(
    kind: str,
    data,
    saturation_level,
    camera,
    layout,
    pol45_toward: str,
    sun_altitude_deg=None,
    pitch_deg=None,
    roll_deg=None,
    mask=None,
    max_samples: int = FRAME_CHECK_MAX_SAMPLES,
) -> dict:
    """
    Check one frame's polarizer convention on a decimated grid: cheap enough for every frame.

    :func:`check_polarizer` on every k-th 2 x 2 block of a raw mosaic (the layout's phase kept)
    or every k-th pixel of Stokes planes, k the smallest step that keeps at most ``max_samples``.
    At the given sun altitude (fast, ~0.1 s for eight hypotheses); when that disfavours the
    configuration (:func:`gate_result`) the check is repeated with the altitude fitted (~0.5-2 s)
    and that report is returned: a wrong or guessed altitude alone never condemns a convention
    (the real ``image0`` frame at its guessed altitude: ``contradicted``, fitted: ``supported``).

    Parameters
    ----------
    kind : {"mosaic", "stokes"}
        A raw full-sensor mosaic, or ``(S0, S1, S2)`` in the camera SDK's convention at the
        sensor's or the superpixels' size.
    data : numpy.ndarray or tuple of numpy.ndarray
        The mosaic (H, W) or the three Stokes planes.
    saturation_level : float or None
        Saturated raw count (mosaic); None: nothing is saturated.
    camera : CameraModel
        The lens of the frame.
    layout : array_like of shape (2, 2) or MosaicLayout
        Configured 2 x 2 polarizer angles [deg].
    pol45_toward : str
        Configured direction of the +45 deg polarizer, ``"+x+y"`` or ``"+x-y"``.
    sun_altitude_deg : float, optional
        Sun altitude [deg]; None fits it (slower).
    pitch_deg, roll_deg : float, optional
        Known camera pitch and roll [deg] (eq 21); None: level.
    mask : numpy.ndarray of bool, optional
        True = sky, at the Stokes planes' size, or for a mosaic the sensor's or the superpixels'.
    max_samples : int, default FRAME_CHECK_MAX_SAMPLES
        Most blocks or pixels fitted.

    Returns
    -------
    dict
        :func:`check_polarizer`'s report (with ``sun_altitude`` when it was refitted).

    """
    from .estimators.mosaic_input import _grid_rays

    if kind == 'mosaic':
        small, k, nx, ny = decimated_blocks(np.asarray(data), max_samples)
        grid = ((1.5, 2.0 * k, nx), (1.5, 2.0 * k, ny))
        item = ('mosaic', small, saturation_level)
        if mask is not None:
            step = 2 * k if mask.shape == camera.shape else k
            mask = mask[::step, ::step][:ny, :nx]
    else:
        h, w = data[0].shape
        k = max(1, int(math.ceil(math.sqrt(h * w / max(int(max_samples), 1)))))
        planes = tuple(np.ascontiguousarray(np.asarray(a)[::k, ::k]) for a in data)
        ny, nx = planes[0].shape
        start, step = (1.0, float(k)) if (h, w) == camera.shape else (1.5, 2.0 * k)
        grid = ((start, step, nx), (start, step, ny))
        item = ('stokes', planes, None)
        mask = None if mask is None else mask[::k, ::k]

    def rays_for_shape(_shape):
        return _grid_rays(camera, *grid)[2:]

    def run(alt):
        return check_polarizer(
            [item],
            camera,
            layout,
            pol45_toward,
            rays_for_shape,
            alt,
            pitch_deg or 0.0,
            roll_deg or 0.0,
            None if mask is None else [np.asarray(mask, bool)],
        )

    rep = run(sun_altitude_deg)
    if sun_altitude_deg is not None and disfavoured(rep):  # a wrong altitude must not condemn
        rep = run(None)
        rep['sun_altitude'] = 'fitted (the given altitude disfavoured the configuration)'
    return rep


def contradiction_text(report: dict) -> str:
    """
    Say that the sky contradicts (or clearly disfavours) the configured convention, and the fix.

    Parameters
    ----------
    report : dict
        A report of :func:`check_polarizer` whose best hypothesis is not the configured one.

    Returns
    -------
    str
        One line: the margin, the reason and the setting that fixes it.

    """
    if report['verdict'] == 'contradicted':
        why = f'contradicted by the sky (margin {report["margin"]:.2f}): {report["reason"]}'
    else:
        why = (
            f'disfavoured by the sky: {report["best"]} fits better by '
            f'{report["configured_deficit"]:.3f} in mean robust loss (a verdict needs '
            f'{DECISIVE_MARGIN}, a heading is refused from {GATE_MARGIN})'
        )
    return f'polarizer convention {why}; fix: {report.get("fix", "")}'


def gate_result(result, report: dict | None):
    """
    Refuse a heading the polarizer check contradicts: never ``ok`` under a wrong convention.

    Parameters
    ----------
    result : HeadingResult
        A method's result on the frame.
    report : dict or None
        :func:`check_polarizer`'s report on the frame (or the last decisive one); None: no check.

    Returns
    -------
    HeadingResult
        ``result`` unless the result has a heading (any status) and the report is
        ``contradicted`` or, undecided, has another best hypothesis that beats the configured one
        by :data:`GATE_MARGIN`: then status ``poor_fit`` with :func:`contradiction_text` as the
        reason, before the result's own reason when it was not ``ok`` already (the heading is
        still reported, as for every ``poor_fit``).

    """
    import dataclasses

    from .estimators.base import Status

    if report is None or result.psi_deg is None or not disfavoured(report):
        return result
    reason = contradiction_text(report)
    if not result.ok and result.reason:
        reason += f' (and: {result.reason})'
    return dataclasses.replace(
        result,
        status=Status.POOR_FIT,
        reason=reason,
        extras={**result.extras, 'polarizer_check': 'contradicted'},
    )


def disfavoured(report: dict) -> bool:
    """
    Return whether a report contradicts the configured convention or favours another.

    Parameters
    ----------
    report : dict
        A :func:`check_polarizer` report.

    Returns
    -------
    bool
        True when ``contradicted``, or when another hypothesis is the best and beats the
        configured one by at least :data:`GATE_MARGIN` in mean robust loss.

    """
    if report.get('verdict') == 'contradicted':
        return True
    return (
        report.get('best') not in (None, report['configured'])
        and (report.get('configured_deficit') or 0.0) >= GATE_MARGIN
    )


def _fit_hypothesis(h, inputs, alts, rays_for_shape, masks, pitch_deg, roll_deg) -> dict:
    """Fit the sky to every input under hypothesis ``h``: its row (mean loss, per-frame fits)."""
    total, frames, usable = 0.0, [], True
    for n, (kind, data, sat) in enumerate(inputs):
        a, d, v, s0 = _aop_for(kind, data, h, sat)
        rays, has_ray = rays_for_shape(a.shape)
        keep = data_mask(s0, has_ray.reshape(a.shape), float('inf') if kind == 'mosaic' else None)
        if masks is not None and masks[n] is not None:
            keep &= masks[n]
        sample = sample_sky(a, d, v & keep, rays)
        if sample is None:
            usable = False
            frames.append({'status': 'too_few_pixels'})
            continue
        f = fit_sky(sample, alts[n], pitch_deg, roll_deg)
        total += f.loss
        frames.append(
            {
                'psi_deg': round(f.psi_deg, 2),
                'sun_altitude_deg': round(f.sun_altitude_deg, 1),
                'loss': round(f.loss, 4),
                'scatter_deg': round(f.scatter_deg, 2),
                'inlier_fraction': round(f.inlier_fraction, 3),
            }
        )
    return {
        'hypothesis': h.describe(),
        'loss': round(total / len(inputs), 4) if usable else None,
        'frames': frames,
    }


def _rank(rows: list, configured: Hypothesis, n_inputs: int) -> dict:
    """Rank the hypotheses' rows (the configured one first) into the verdict, reason and fix."""
    scored = [r for r in rows if r['loss'] is not None]
    out = {'configured': configured.describe(), 'hypotheses': rows, 'frames': n_inputs}
    if len(scored) < 2:
        out.update(
            verdict='cannot_tell',
            reason='too few usable sky pixels under the hypotheses',
            margin=0.0,
            best=None,
        )
        return out
    ranked = sorted(scored, key=lambda r: r['loss'])
    best, second = ranked[0], ranked[1]
    margin = second['loss'] - best['loss']
    out['best'] = best['hypothesis']
    out['margin'] = round(margin, 4)
    conf = rows[0]
    out['configured_deficit'] = (
        None if conf['loss'] is None else round(conf['loss'] - best['loss'], 4)
    )
    if margin < DECISIVE_MARGIN:
        out['verdict'] = 'cannot_tell'
        out['reason'] = (
            f'the best two hypotheses differ by {margin:.3f} in mean robust loss (need '
            f'{DECISIVE_MARGIN}): the sky does not decide (sun near an image axis or the zenith, '
            'overcast, or too little sky)'
        )
    elif best is conf:
        out['verdict'] = 'supported'
        out['reason'] = f'the configured convention fits best, by {margin:.3f} over the runner-up'
    else:
        out['verdict'] = 'contradicted'
        out['reason'], out['fix'] = _contradiction(best, conf)
    if best is not conf and 'fix' not in out:  # undecided, but the configuration is not the best
        out['fix'] = _contradiction(best, conf)[1]
    return out


def _contradiction(best: dict, conf: dict) -> tuple:
    """Say why the configured convention lost to ``best``, and the setting that fixes it."""
    b = best['hypothesis']
    reason = (
        f'the sky fits {b} better than the configured convention by '
        f'{(conf["loss"] or 0) - best["loss"]:.3f}'
        if conf['loss'] is not None
        else f'the sky fits {b} and the configured convention leaves too few usable pixels'
    )
    fix = (
        f"set polarizer: {{layout: {b['layout']}, pol45_toward: '{b['pol45_toward']}'}} in "
        'CAMERA.yaml '
        '(node parameters polarizer_layout: '
        f'"{",".join(str(v) for r in b["layout"] for v in r)}", '
        f'pol45_toward: "{b["pol45_toward"]}")'
    )
    if b['pol45_toward'] != conf['hypothesis']['pol45_toward']:  # a mirror: maybe the readout's
        fix += (
            '; but if the camera mirrors its readout (GenICam ReverseX/ReverseY), a layout '
            'cannot undo the mirrored geometry (headings would be mirrored): keep the '
            "sensor's polarizer and set readout_flip: x, y or xy in CAMERA.yaml instead "
            '(docs/real-cameras.md)'
        )
    elif b['layout'] != conf['hypothesis']['layout']:  # a phase: maybe a 180 deg readout
        fix += (
            '; but if the camera rotates its readout by 180 deg (ReverseX and ReverseY), keep '
            "the sensor's layout and set readout_flip: xy in CAMERA.yaml instead (the layout "
            'alone leaves every heading 180 deg off; docs/real-cameras.md)'
        )
    return reason, fix
