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
Allowable tilt: the largest pitch/roll envelope keeping the heading error bounded.

The bound holds for every method (paper, section 3.4); the envelope is read from an error map,
beside the paper's rule of thumb, eq 33.

Eq 33, ``h_s * sqrt(alpha^2 + beta^2) <= ME^2``, is homogeneous of degree 2 in angle on both sides,
so it gives the same answer in degrees or radians as long as all four quantities use the same unit
(it is not a mixed-units formula, only an empirical one): the allowed tilt radius is ``ME^2 /
h_s``, and unbounded at h_s = 0.

From the map, for one sun altitude: ``worst(p, r)`` = the largest |error| over every method and
every yaw at the (pitch, roll) node. The envelope is a disc (the shape eq 33 assumes): its radius
is the largest node radius ``sqrt(p^2 + r^2)`` such that every node at or inside it has ``worst <=
ME``; the first failing radius and a linear estimate of the crossing are reported too, as are the
pitch-only and roll-only limits. The answer is only claimed where the map has valid nodes
(``coverage``): beyond, it reads "at least".
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
import math

import numpy as np

from .errormap import ErrorMap, ErrorMapError

__all__ = ['Envelope', 'allowable_envelope', 'eq33_radius_deg', 'format_envelopes']


def eq33_radius_deg(max_error_deg: float, sun_altitude_deg: float) -> float:
    """
    Compute eq 33's allowed tilt radius ``sqrt(pitch^2 + roll^2) = ME^2 / h_s``.

    Eq 33 is homogeneous of degree 2 in angle on both sides, so degrees in give degrees out.

    Parameters
    ----------
    max_error_deg : float
        Allowed heading error ME [deg].
    sun_altitude_deg : float
        Sun altitude h_s [deg].

    Returns
    -------
    float
        Tilt radius [deg]; inf at h_s <= 0.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 33 (Sec. 3.4).

    """
    if sun_altitude_deg <= 0:
        return math.inf
    return max_error_deg**2 / sun_altitude_deg


@dataclass(frozen=True)
class Envelope:
    """
    Hold the allowable tilt envelope at one sun altitude; angles in degrees.

    ``None`` means "not reached inside the map's coverage".

    Parameters
    ----------
    sun_altitude_deg : float
        Sun altitude [deg].
    max_error_deg : float
        Heading error bound ME [deg].
    methods : tuple of str
        Methods whose worst error counts.
    radius_ok_deg : float
        Every node with tilt radius at most this [deg] meets the bound.
    radius_fail_deg : float or None
        Smallest radius [deg] of a node that does not (None: none within coverage).
    radius_estimate_deg : float
        Linear estimate [deg] of the crossing between the two.
    coverage_deg : float
        Radius [deg] up to which the map has every node valid.
    pitch_only_deg, roll_only_deg : tuple or None
        ``(limit_deg, reached)`` along roll 0 (pitch 0); reached False reads ">= limit".
    eq33_radius_deg : float
        Eq 33's radius [deg] (:func:`eq33_radius_deg`).
    worst_at_eq33_deg : float or None
        The map's worst error [deg] inside eq 33's disc (None: beyond coverage).
    worst_method : str or None
        The method failing first.
    verdict : str
        Eq 33 against the map, one line.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 33 (Sec. 3.4).

    """

    sun_altitude_deg: float
    max_error_deg: float
    methods: tuple
    radius_ok_deg: float  # every node with radius <= this meets the bound
    radius_fail_deg: (
        float | None
    )  # the smallest radius of a node that does not (None: none within coverage)
    radius_estimate_deg: float  # linear estimate of the crossing between the two
    coverage_deg: float  # radius up to which the map has every node valid
    pitch_only_deg: tuple | None  # (limit, reached) along roll 0; reached False: ">= limit"
    roll_only_deg: tuple | None
    eq33_radius_deg: float
    worst_at_eq33_deg: (
        float | None
    )  # the map's worst error inside eq 33's disc (None: beyond coverage)
    worst_method: str | None  # the method failing first
    verdict: str

    def to_json_dict(self) -> dict:
        """
        Convert the envelope to a JSON-ready dict (inf becomes None).

        Returns
        -------
        dict
            The fields by name; the pitch/roll-only tuples as ``{"limit_deg", "reached"}``.

        """
        d = asdict(self)
        for k in ('pitch_only_deg', 'roll_only_deg'):
            if d[k] is not None:
                d[k] = {'limit_deg': d[k][0], 'reached': d[k][1]}
        return {
            k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()
        }


def _worst_at(m: ErrorMap, ia_list, methods_idx):
    """
    Return the worst |error| over methods, yaws and altitudes per (pitch, roll).

    (P, R) worst |error| over methods and yaws and the listed altitudes; validity (P, R); worst
    method.
    """
    e = np.abs(m.error_deg[np.ix_(methods_idx, ia_list)])  # (M, A', Y, P, R)
    v = m.valid[np.ix_(methods_idx, ia_list)]
    ok = v.all(axis=(0, 1, 2))
    worst = np.where(v, e, 0.0).max(axis=(1, 2))  # (M, P, R)
    return worst.max(axis=0), ok, worst


def _line_limit(values_abs, worst, me):
    """
    Along a line of nodes: (limit, reached).

    ``limit`` is the linear estimate of where the worst error
    (running max by |x|) crosses ``me``; if no node fails, the largest |x| with reached = False.
    """
    order = np.argsort(values_abs, kind='stable')
    xs, ws = values_abs[order], np.maximum.accumulate(worst[order])
    fail = np.nonzero(ws > me)[0]
    if fail.size == 0:
        return float(xs[-1]), False
    k = int(fail[0])
    if k == 0:
        return 0.0, True
    x0, w0, x1, w1 = xs[k - 1], ws[k - 1], xs[k], ws[k]
    est = x0 + (x1 - x0) * (me - w0) / (w1 - w0) if w1 > w0 else x0
    return float(np.clip(est, x0, x1)), True


def allowable_envelope(
    m: ErrorMap, max_error_deg: float, sun_altitude_deg: float, methods=None
) -> Envelope:
    """
    Read the allowable tilt envelope at one sun altitude from an error map.

    Off the altitude nodes, the two bracketing nodes are combined (worst of both: the error grows
    with altitude, so this is the conservative side). See the module docstring for the disc and its
    radii.

    Parameters
    ----------
    m : ErrorMap
        The tilt error map.
    max_error_deg : float
        Heading error bound ME [deg], > 0.
    sun_altitude_deg : float
        Sun altitude [deg], within the map's altitude axis.
    methods : sequence of str, optional
        Methods whose worst error counts; all of the map's by default.

    Returns
    -------
    Envelope
        The radii [deg], the pitch- and roll-only limits, eq 33's radius and the verdict.

    Raises
    ------
    ErrorMapError
        A non-positive bound, an altitude outside the map, an unknown method, or no valid node at
        this altitude.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), Sec. 3.4 and eq 33.

    """
    if not (math.isfinite(max_error_deg) and max_error_deg > 0):
        raise ErrorMapError(f'the error bound must be > 0 deg, got {max_error_deg}')
    alt = m.sun_altitude_deg
    if not (alt[0] - 1e-9 <= sun_altitude_deg <= alt[-1] + 1e-9):
        raise ErrorMapError(
            f'sun altitude {sun_altitude_deg:g} deg is outside the map ({alt[0]:g}..{alt[-1]:g})'
        )
    j = int(np.argmin(np.abs(alt - sun_altitude_deg)))
    if abs(alt[j] - sun_altitude_deg) <= 1e-6:
        ia_list = [j]
    else:
        k = int(np.searchsorted(alt, sun_altitude_deg))
        ia_list = [k - 1, k]
    names = list(m.methods) if methods is None else list(methods)
    midx = [m.method_index(n) for n in names]
    worst, ok, per_method = _worst_at(m, ia_list, midx)
    P, R = np.meshgrid(m.pitch_deg, m.roll_deg, indexing='ij')
    rad = np.hypot(P, R)
    dom = m.meta.get('domain', {}) if isinstance(m.meta, dict) else {}
    limit = (
        math.inf if dom.get('full_domain', False) else float(dom.get('tilt_limit_deg', math.inf))
    )
    in_domain = (np.abs(P) + np.abs(R)) <= limit + 1e-9
    ok = ok & in_domain  # support nodes beyond the tilt limit are not part of the answer
    coverage = limit / math.sqrt(2.0)  # the largest disc inside |pitch| + |roll| <= limit
    if (~ok).any():
        coverage = min(coverage, float(rad[~ok].min()) - 1e-9)
    inside = ok & (rad <= coverage + 1e-9)
    r_in, w_in = rad[inside], worst[inside]
    if r_in.size == 0:
        raise ErrorMapError('the map has no valid node at this sun altitude')
    # disc: sort nodes by radius, running max of worst
    order = np.argsort(r_in, kind='stable')
    rs, ws = r_in[order], np.maximum.accumulate(w_in[order])
    fail = np.nonzero(ws > max_error_deg)[0]
    worst_method = None
    if fail.size == 0:
        r_ok, r_fail = float(rs[-1]), None
        est = r_ok
    else:
        k = int(fail[0])
        r_fail = float(rs[k])
        r_ok = float(rs[k - 1]) if k > 0 else 0.0
        w0 = float(ws[k - 1]) if k > 0 else 0.0
        w1 = float(ws[k])
        # the last passing radius may share its value with the failing one (several nodes per
        # radius)
        passing = rs[:k][rs[:k] < r_fail - 1e-9]
        r_ok = float(passing[-1]) if passing.size else 0.0
        est = r_ok + (r_fail - r_ok) * (max_error_deg - w0) / (w1 - w0) if w1 > w0 else r_ok
        est = float(np.clip(est, r_ok, r_fail))
        node = np.argwhere(inside & (np.abs(rad - r_fail) < 1e-9) & (worst > max_error_deg))[0]
        worst_method = names[int(np.argmax(per_method[:, node[0], node[1]]))]
    # pitch-only / roll-only lines: (crossing estimate, or the largest node when every node passes)
    pitch_only = roll_only = None
    if np.any(np.abs(m.roll_deg) < 1e-9):
        ir = int(np.argmin(np.abs(m.roll_deg)))
        line = ok[:, ir]
        if line.any():
            pitch_only = _line_limit(np.abs(m.pitch_deg[line]), worst[line, ir], max_error_deg)
    if np.any(np.abs(m.pitch_deg) < 1e-9):
        ip = int(np.argmin(np.abs(m.pitch_deg)))
        line = ok[ip, :]
        if line.any():
            roll_only = _line_limit(np.abs(m.roll_deg[line]), worst[ip, line], max_error_deg)
    r33 = eq33_radius_deg(max_error_deg, float(sun_altitude_deg))
    worst33 = None
    if r33 <= (coverage if math.isfinite(coverage) else rs[-1]):
        sel = rs <= r33 + 1e-9
        worst33 = float(ws[sel][-1]) if sel.any() else 0.0
    verdict = _verdict(max_error_deg, r_ok, r_fail, est, coverage, r33, worst33)
    return Envelope(
        float(sun_altitude_deg),
        float(max_error_deg),
        tuple(names),
        r_ok,
        r_fail,
        est,
        coverage if math.isfinite(coverage) else float(rs[-1]),
        pitch_only,
        roll_only,
        r33,
        worst33,
        worst_method,
        verdict,
    )


def _verdict(me, r_ok, r_fail, est, coverage, r33, worst33) -> str:
    """
    Eq 33 against the map.

    The map's limit is ``est`` (linear between the last passing and the first failing node radius).
    Eq 33 is optimistic when its radius exceeds that, conservative when it is less than half of it
    (a factor of 2 is what one grid step typically spans), else they agree.
    """
    lim = (
        f">= {r_ok:.3g} deg (no node within the map's coverage fails)"
        if r_fail is None
        else f'~{est:.3g} deg (nodes pass to {r_ok:.3g}, fail from {r_fail:.3g})'
    )
    if not math.isfinite(r33):
        return f"eq 33 sets no limit at sun altitude 0; the map's limit is {lim}"
    if r_fail is None and r33 > coverage:
        return (
            f"cannot compare: eq 33 allows {r33:.3g} deg, beyond the map's coverage "
            f'({coverage:.3g} deg), '
            f'inside which every node passes'
        )
    if (worst33 is not None and worst33 > me * (1 + 1e-9)) or (
        r_fail is not None and r33 > est * (1 + 1e-9)
    ):
        extra = (
            f"; the map's worst node error inside it is {worst33:.3g} deg > {me:g}"
            if worst33 is not None and worst33 > me
            else ''
        )
        return f'DISAGREE, eq 33 is optimistic: it allows {r33:.3g} deg, the map {lim}{extra}'
    if r33 < 0.5 * (est if r_fail is not None else r_ok):
        factor = (est if r_fail is not None else r_ok) / r33 if r33 > 0 else math.inf
        return (
            f"DISAGREE, eq 33 is conservative: {r33:.3g} deg against the map's {lim}, "
            f'{"at least " if r_fail is None else ""}{factor:.3g} x smaller'
        )
    return f'agree within a factor of 2: eq 33 gives {r33:.3g} deg, the map {lim}'


def format_envelopes(envs) -> str:
    """
    Format envelopes as a fixed-width table (one line per sun altitude) plus the verdicts.

    Parameters
    ----------
    envs : sequence of Envelope
        Envelopes with the same bound and methods (the header reads the first).

    Returns
    -------
    str
        The table, angles in degrees.

    """

    def f(v):
        if isinstance(v, tuple):
            return f'~{v[0]:.2f}' if v[1] else f'>={v[0]:.2f}'
        return (
            '-' if v is None else ('inf' if isinstance(v, float) and math.isinf(v) else f'{v:.2f}')
        )

    head = (
        f'{"sun alt":>8} {"radius ok":>10} {"fails at":>9} {"~limit":>8} {"pitch-only":>11} '
        f'{"roll-only":>10} '
        f'{"eq33":>8} {"map worst@eq33":>15} {"coverage":>9}  first to fail'
    )
    lines = [
        f'max error {envs[0].max_error_deg:g} deg, methods {", ".join(envs[0].methods)} '
        '(tilt radius = sqrt(pitch^2 + roll^2), deg)',
        head,
    ]
    for e in envs:
        lines.append(
            f'{e.sun_altitude_deg:>8.2f} {f(e.radius_ok_deg):>10} {f(e.radius_fail_deg):>9} '
            f'{f(e.radius_estimate_deg):>8} {f(e.pitch_only_deg):>11} {f(e.roll_only_deg):>10} '
            f'{f(e.eq33_radius_deg):>8} {f(e.worst_at_eq33_deg):>15} {f(e.coverage_deg):>9}  '
            f'{e.worst_method or "-"}'
        )
    lines.append('')
    lines += [f'h = {e.sun_altitude_deg:g} deg: {e.verdict}' for e in envs]
    return '\n'.join(lines)
