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
Where the sun was: per image stamp for the current site (live), or once for an input file.

:class:`SunSource` gives the nodes and the replay the sun at each image stamp;
:func:`resolve_sun` says where the sun was for an input file (given, from a frame's meta, or from
the ephemeris) as a :class:`Sun`.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .errors import PipelineError
from ..errors import CompassError

__all__ = [
    'Sun',
    'SunSource',
    'resolve_sun',
]


# ------------------------------------------------------------------------------------------------
# The sun per stamp
# ------------------------------------------------------------------------------------------------
class SunSource:
    """
    Give the sun's azimuth and altitude at a UTC stamp for the current site.

    Through :class:`~polarization_compass.solar.SunCache` (one SPA batch per 10 minutes of stamps).

    Parameters
    ----------
    latitude_deg : float
        Site latitude [deg], north positive.
    longitude_deg : float
        Site longitude [deg], east positive.
    altitude_m : float
        Site height above sea level [m].
    model : {"spa", "paper"}, default "spa"
        Sun position model (:mod:`~polarization_compass.solar`).

    References
    ----------
    .. [1] I. Reda and A. Andreas, "Solar position algorithm for solar radiation applications",
       Solar Energy 76(5): 577-589, 2004.

    """

    def __init__(
        self, latitude_deg: float, longitude_deg: float, altitude_m: float, model: str = 'spa'
    ):
        self.model = model
        self._site = None
        self._cache = None
        self.set_site(latitude_deg, longitude_deg, altitude_m)

    def set_site(self, latitude_deg: float, longitude_deg: float, altitude_m: float) -> None:
        """
        Move the site; a new sun cache only when the sun would move by more than ~1e-5 deg.

        Parameters
        ----------
        latitude_deg : float
            Site latitude [deg], north positive.
        longitude_deg : float
            Site longitude [deg], east positive.
        altitude_m : float
            Site height above sea level [m].

        """
        site = (float(latitude_deg), float(longitude_deg), float(altitude_m))
        if self._site is not None:
            # a GNSS fix moves by metres: a new cache only when the sun would move by > ~1e-5 deg
            if (
                abs(site[0] - self._site[0]) < 1e-5
                and abs(site[1] - self._site[1]) < 1e-5
                and abs(site[2] - self._site[2]) < 100.0
            ):
                return
        from ..solar import SunCache

        self._cache = SunCache(*site, model=self.model)
        self._site = site

    @property
    def site(self):
        """Return the current site ``(latitude_deg, longitude_deg, altitude_m)``."""
        return self._site

    def at_ns(self, t_ns: int) -> tuple[float, float]:
        """
        Compute the sun at a UTC stamp.

        Parameters
        ----------
        t_ns : int
            UTC stamp [ns since the Unix epoch].

        Returns
        -------
        azimuth_deg : float
            Sun azimuth [deg], clockwise from North.
        altitude_deg : float
            Sun altitude [deg] as the model gives it.

        Raises
        ------
        PipelineError
            The sun model refuses the stamp (the message says why).

        """
        from ..solar import SolarError

        t_us = np.datetime64(int(t_ns) // 1000, 'us')
        try:
            p = self._cache(t_us)
        except SolarError as exc:
            raise PipelineError(f'sun position at stamp {t_ns / 1e9:.3f} s: {exc}') from None
        return float(p.azimuth_deg), float(p.altitude_deg)


# ------------------------------------------------------------------------------------------------
# The sun of an input file
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Sun:
    """Where the sun was: azimuth [deg, clockwise from North], altitude [deg] and whence."""

    azimuth_deg: float
    altitude_deg: float
    source: str


def resolve_sun(
    meta: dict,
    azimuth_deg: float | None = None,
    altitude_deg: float | None = None,
    lat_deg: float | None = None,
    lon_deg: float | None = None,
    time_utc: str | None = None,
) -> Sun:
    """
    Say where the sun was: given, else from a frame's meta, else from the ephemeris.

    Parameters
    ----------
    meta : dict
        A frame's meta (``sun_azimuth_deg``, ``sun_altitude_deg``); ``{}`` for a real image.
    azimuth_deg, altitude_deg : float, optional
        The given sun [deg]; both or neither (the caller checks their ranges).
    lat_deg, lon_deg : float, optional
        The site [deg], for the ephemeris.
    time_utc : str, optional
        UTC time, ISO 8601, for the ephemeris.

    Returns
    -------
    Sun
        Azimuth, altitude and where they came from.

    Raises
    ------
    CompassError
        Nothing says where the sun was.

    """
    if azimuth_deg is not None or altitude_deg is not None:
        return Sun(float(azimuth_deg), float(altitude_deg), 'given (--sun-azimuth/--sun-altitude)')
    az, alt = meta.get('sun_azimuth_deg'), meta.get('sun_altitude_deg')
    ok = all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        for v in (az, alt)
    )
    if ok:
        return Sun(float(az), float(alt), 'frame meta')
    if lat_deg is None or lon_deg is None or time_utc is None:
        raise CompassError(
            'the input does not say where the sun was: give --lat, --lon and --time, or '
            '--sun-azimuth and --sun-altitude'
        )
    from ..solar import sun_position

    pos = sun_position(time_utc, lat_deg, lon_deg, 0.0)
    return Sun(
        float(pos.azimuth_deg),
        float(pos.altitude_deg),
        'ephemeris (SPA) for --lat/--lon/--time',
    )
