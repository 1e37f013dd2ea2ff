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
"""Where the site and the sun come from: the parameters of every node that computes the sun."""

from __future__ import annotations

from .spec import Param

SITE = (
    Param(
        'latitude_deg', 32.026778, 'site latitude, north positive (WGS84)', -90.0, 90.0, unit='deg'
    ),
    Param(
        'longitude_deg',
        118.853306,
        'site longitude, east positive (WGS84)',
        -180.0,
        180.0,
        unit='deg',
    ),
    Param('altitude_m', 30.0, 'site height above sea level', -1000.0, 20000.0, unit='m'),
)

#: The parameters the sun's position depends on: a node makes a new :func:`sun_source` when one
#: changes.
SUN_PARAMS = ('latitude_deg', 'longitude_deg', 'altitude_m', 'sun_model')


def sun_source(values):
    """
    Return the :class:`~polarization_compass.pipeline.SunSource` of a node's site parameters.

    Parameters
    ----------
    values : mapping
        Holds :data:`SUN_PARAMS`: ``latitude_deg`` and ``longitude_deg`` [deg, WGS84, north and
        east positive], ``altitude_m`` [m] and ``sun_model``.

    Returns
    -------
    SunSource
        The sun's position source at that site.

    """
    from ...pipeline import SunSource

    return SunSource(*(values[k] for k in SUN_PARAMS))


#: Where a node takes the site from (heading_estimator and tilt_corrector: the same choice in a
#: graph).
SITE_SOURCE = Param(
    'site_source',
    'parameters',
    'where the site comes from: parameters (latitude_deg, longitude_deg, altitude_m) or navsatfix '
    '(gps/fix, the latest fix; until the first fix nothing that needs the sun is published, a '
    'status '
    'says why)',
    choices=('parameters', 'navsatfix'),
    read_only=True,
)


def apply_fix(sun, diag, msg):
    """
    Move ``sun`` to the site of a sensor_msgs/NavSatFix.

    A fix :func:`~polarization_compass.bag.decode_navsatfix` refuses is counted on ``diag`` as
    rejected ``fix_<reason>``; a site the ephemeris refuses as ``fix_bad_value`` (``sun`` keeps
    its site then).

    Parameters
    ----------
    sun : SunSource
        The node's sun source, updated in place.
    diag : Diagnostics
        The node's :class:`~polarization_compass.nodes.diagnostics.Diagnostics` (counts
        rejections).
    msg : sensor_msgs.msg.NavSatFix
        The fix.

    Returns
    -------
    tuple of float or None
        The site ``(latitude_deg, longitude_deg, altitude_m)``, or None when the fix was rejected.

    """
    from ...bag import decode_navsatfix
    from ...errors import CompassError

    site = diag.decoded('fix', decode_navsatfix, msg)
    if site is None:
        return None
    try:
        sun.set_site(*site)
    except CompassError as exc:
        diag.reject('fix_bad_value', str(exc))
        return None
    return site
