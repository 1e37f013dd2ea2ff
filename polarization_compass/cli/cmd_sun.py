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

"""`polarization-compass sun`: the sun's azimuth and altitude at a site and UTC time, as JSON."""

from __future__ import annotations

import datetime as _dt
import json
import sys


def register(sub):
    p = sub.add_parser(
        'sun',
        help='solar azimuth/altitude for a site and time (JSON)',
        description='Sun position: azimuth clockwise from true North, geometric altitude and '
        '(model spa) apparent altitude with refraction, all in degrees.',
    )
    p.add_argument('--lat', type=float, required=True, help='latitude, deg north (-90..90)')
    p.add_argument('--lon', type=float, required=True, help='longitude, deg east (-180..180)')
    p.add_argument(
        '--time', required=True, help='ISO 8601 time, e.g. 2019-11-15T06:00:00Z (no zone = UTC)'
    )
    p.add_argument(
        '--model',
        choices=('spa', 'paper'),
        default='spa',
        help="spa: NREL SPA via pvlib (default); paper: the paper's eqs 2-10",
    )
    p.add_argument(
        '--altitude-m', type=float, default=0.0, help='site height above sea level, m (default 0)'
    )
    p.add_argument(
        '--pressure-hpa',
        type=float,
        help='air pressure for refraction, hPa (default: standard atmosphere at --altitude-m)',
    )
    p.add_argument(
        '--temperature-c',
        type=float,
        default=12.0,
        help='air temperature for refraction, C (default 12)',
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from ..solar import sun_position, to_epoch_us

    pos = sun_position(
        args.time,
        args.lat,
        args.lon,
        args.altitude_m,
        model=args.model,
        pressure_hpa=args.pressure_hpa,
        temperature_c=args.temperature_c,
    )
    us = int(to_epoch_us(args.time)[0].reshape(-1)[0])
    t = _dt.datetime(1970, 1, 1, tzinfo=_dt.timezone.utc) + _dt.timedelta(microseconds=us)
    out = {'azimuth_deg': pos.azimuth_deg, 'altitude_deg': pos.altitude_deg}
    if pos.apparent_altitude_deg is not None:
        out['apparent_altitude_deg'] = pos.apparent_altitude_deg
    out.update(
        {
            'model': args.model,
            'time_utc': t.isoformat().replace('+00:00', 'Z'),
            'latitude_deg': args.lat,
            'longitude_deg': args.lon,
        }
    )
    if args.model == 'spa':
        out['altitude_m'] = args.altitude_m
    json.dump(out, sys.stdout)
    sys.stdout.write('\n')
    return 0
