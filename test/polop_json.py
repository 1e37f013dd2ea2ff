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
Test-side converter for the real POL-OP recordings' JSON layout.

The recordings are in ../shared/data/real-polop (GPL-3.0: read from there at test time, never
copied into the repository). See that folder's README.md.

Each ``<session>/N.json`` (one full turn) holds ``pol_op_0`` .. ``pol_op_7`` (samples of ``[I135,
I045, I090, I000]``, raw signed: absolute values used), ``azimuths`` (rad, the units' viewing
azimuths relative to the front, clockwise as the README establishes) and ``yaw`` (IMU, rad,
counter-clockwise). The reference heading of the front, clockwise from North, is ``H0 -
degrees(unwrap(yaw))`` with ``H0`` the session's ``H0_intensity_deg`` (sessions.csv; good to about
+-5 deg per turn).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
import json
import os
from pathlib import Path

import numpy as np


def _data_dir() -> Path:
    """
    Return the directory of the real POL-OP data.

    ``$POLOP_DATA_DIR`` when set, else ``../shared/data/real-polop`` beside the checkout (or one
    level up, for worktrees kept in a subfolder).
    """
    if os.environ.get('POLOP_DATA_DIR'):
        return Path(os.environ['POLOP_DATA_DIR']).resolve()
    repo = Path(__file__).resolve().parents[1]
    for base in (repo.parent, repo.parent.parent):
        cand = base / 'shared' / 'data' / 'real-polop'
        if cand.is_dir():
            return cand
    return repo.parent / 'shared' / 'data' / 'real-polop'


DATA_DIR = _data_dir()
CHANNELS_DEG = (135.0, 45.0, 90.0, 0.0)
ELEVATION_DEG = 45.0
#: seconds between consecutive turns of a session: the README's 15-20 minutes for 12 turns, taken
#: as 90 s
TURN_SPACING_S = 90.0


def available() -> bool:
    return (DATA_DIR / 'sessions.csv').is_file()


def skip_reason() -> str:
    return (
        f'real POL-OP recordings not found at {DATA_DIR} (GPL-3.0 data kept outside the '
        'repository)'
    )


@dataclass
class Turn:
    session: str
    index: int  # N of N.json
    intensities: np.ndarray  # (S, 8, 4) absolute readings, channels 135, 45, 90, 0 deg
    azimuths_deg: np.ndarray  # (8,)
    reference_bearing_deg: np.ndarray  # (S,) front, clockwise from North
    time_utc: str  # session start (UTC, ISO 8601)
    t_offset_s: float  # this turn's assumed offset after time_utc
    sky: str  # "clear" or "trees"


def sessions() -> list[dict]:
    with open(DATA_DIR / 'sessions.csv', newline='', encoding='utf-8') as fh:
        return list(csv.DictReader(fh))


def load_turn(session_row: dict, n: int) -> Turn:
    d = json.loads((DATA_DIR / session_row['session'] / f'{n}.json').read_text(encoding='utf-8'))
    inten = np.abs(np.array([d[f'pol_op_{u}'] for u in range(8)], dtype=float)).transpose(1, 0, 2)
    yaw = np.asarray(d['yaw'], dtype=float)
    ref = (float(session_row['H0_intensity_deg']) - np.degrees(np.unwrap(yaw))) % 360.0
    sky = 'trees' if int(session_row['canopy']) > 0 else 'clear'
    return Turn(
        session_row['session'],
        n,
        inten,
        np.degrees(np.asarray(d['azimuths'], dtype=float)),
        ref,
        session_row['utc'],
        (n - 1) * TURN_SPACING_S,
        sky,
    )


def load_session(session_row: dict) -> list[Turn]:
    return [load_turn(session_row, n) for n in range(1, int(session_row['n_recordings']) + 1)]


def geometry_dict(
    angle_zero: str = 'horizontal', angle_sense: str = 'ccw', disabled=(5, 7)
) -> dict:
    """Return the sensor description of these recordings (units, channel order: README)."""
    az = (0, 90, 180, 270, 45, 135, 225, 315)
    return {
        'angle_zero': angle_zero,
        'angle_sense': angle_sense,
        'units': [
            {
                'azimuth_deg': float(a),
                'elevation_deg': ELEVATION_DEG,
                'channels_deg': list(CHANNELS_DEG),
                'acceptance_deg': 60.0,
                **({'enabled': False} if i in disabled else {}),
            }
            for i, a in enumerate(az)
        ],
    }
