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
`polarization-compass budget`: Monte Carlo heading-error budget of a scene.

The budget is given per method and by source.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import sys


def register(sub):
    p = sub.add_parser(
        'budget',
        help='heading-error budget of a scene: per method RMS/p95/max, share not ok, '
        "sigma calibration, and each declared effect's contribution",
        description='Monte Carlo over the effects a scene declares (sensor noise and calibration, '
        'clouds, haze, skyline, ground, lens optics, sky model) plus tilt and IMU/mounting '
        'errors; each source is switched off in turn on the same samples to give its '
        'contribution. Writes budget.json and budget.png to --out.',
    )
    p.add_argument('--scene', required=True, help='scene YAML (see config/scenes/)')
    p.add_argument(
        '--tilt',
        type=float,
        default=0.0,
        help='random tilt per sample with |pitch| + |roll| <= TILT deg (default 0: level)',
    )
    p.add_argument(
        '--imu',
        default='',
        help='IMU/mounting errors as key=value,...: noise_deg, bias_deg (or pitch_bias_deg, '
        'roll_bias_deg), boresight_deg (or boresight_roll_deg, boresight_pitch_deg, '
        'boresight_yaw_deg), time_offset_s, tilt_rate_deg_s',
    )
    p.add_argument(
        '--correction',
        choices=('error_map', 'none'),
        default='error_map',
        help="what the graph's tilt_corrector does to methods that do not read the tilt: "
        "invert their tilt error with the error map at the IMU's pitch/roll (default; the "
        "attitude's stated uncertainty is propagated into sigma), or none (raw tilt error)",
    )
    p.add_argument(
        '--error-map', default=None, help='error map .npz for the correction (default: shipped)'
    )
    p.add_argument(
        '--correction-sigma',
        type=float,
        default=0.0,
        help="1-sigma of the map's own error for this camera [deg], added in quadrature to "
        "corrected methods' sigmas (the node's correction_sigma_deg; default 0)",
    )
    p.add_argument(
        '--sigma-floor',
        type=float,
        default=None,
        help='smallest sigma counted in the sigma calibration [deg] (default: sigma_floor_deg of '
        'the nodes, 0.01: what a robot receives; 0 = the raw sigma)',
    )
    p.add_argument('--samples', type=int, default=50, help='frames per condition (default 50)')
    p.add_argument(
        '--methods', default='', help='comma-separated methods (default: all registered)'
    )
    p.add_argument(
        '--workers',
        type=int,
        default=1,
        help='Dask LocalCluster worker processes (default 1: in this process, without Dask)',
    )
    p.add_argument(
        '--scheduler', metavar='tcp://HOST:PORT', help='run on this existing Dask cluster'
    )
    p.add_argument('--out', default='budget', help='output directory (default ./budget)')
    p.set_defaults(func=run)


def _writable_dir(out: Path) -> Path:
    """Create ``out`` (and its parents) and check that files can be written into it."""
    from ..budget_config import BudgetError

    if out.exists() and not out.is_dir():
        raise BudgetError(f'--out {str(out)!r} exists and is not a directory')
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BudgetError(f'--out {str(out)!r} cannot be created: {exc.strerror or exc}') from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise BudgetError(f'--out {str(out)!r} is not writable')
    return out


def run(args) -> int:
    from ..budget import plot_budget, run_budget, SIGMA_BAND
    from ..budget_config import BudgetConfig, BudgetError, check_config, parse_imu
    from ..scene import load_scene

    if args.samples < 1 or args.samples > 100000:
        raise BudgetError(f'--samples must be in [1, 100000], got {args.samples}')
    if not (0.0 <= args.tilt <= 60.0):
        raise BudgetError(f'--tilt must be in [0, 60] deg, got {args.tilt}')
    if not (1 <= args.workers <= 256):
        raise BudgetError(f'--workers must be in [1, 256], got {args.workers}')
    if args.scheduler is not None and not args.scheduler.startswith(('tcp://', 'tls://')):
        raise BudgetError(
            f'--scheduler must be an address like tcp://HOST:PORT, got {args.scheduler!r}'
        )
    scene = load_scene(args.scene)
    methods = tuple(m.strip() for m in args.methods.split(',') if m.strip())
    if not (0.0 <= args.correction_sigma <= 90.0):
        raise BudgetError(
            f'--correction-sigma must be in [0, 90] deg, got {args.correction_sigma}'
        )
    extra = {}
    if args.sigma_floor is not None:
        if not (0.0 <= args.sigma_floor <= 90.0):
            raise BudgetError(f'--sigma-floor must be in [0, 90] deg, got {args.sigma_floor}')
        extra['sigma_floor_deg'] = float(args.sigma_floor)
    cfg = BudgetConfig(
        scene,
        int(args.samples),
        float(args.tilt),
        parse_imu(args.imu),
        methods,
        correction=args.correction,
        error_map=args.error_map,
        correction_sigma_deg=float(args.correction_sigma),
        **extra,
    )
    check_config(cfg)
    out = _writable_dir(Path(args.out))  # before the computation, not after it
    result = run_budget(
        cfg,
        progress=lambda name: print(f'budget: {name} ...', file=sys.stderr, flush=True),
        workers=args.workers,
        scheduler=args.scheduler,
    )
    (out / 'budget.json').write_text(json.dumps(result, indent=1, sort_keys=True))
    plot_budget(result, out / 'budget.png')
    fmt = lambda v, f='{:.3f}': '-' if v is None else f.format(v)  # noqa: E731
    print(
        f'{"method":16s} {"rms":>8s} {"p95":>8s} {"max":>8s} {"not ok":>7s} {"sigma cal":>9s}  '
        'largest sources'
    )
    for m in result['methods']:
        st = result['conditions']['all'][m]
        b = result['breakdown'][m]
        top = sorted(((v['contribution_deg'] or 0.0, s) for s, v in b.items()), reverse=True)[:3]
        print(
            f'{m:16s} {fmt(st["rms_deg"]):>8s} {fmt(st["p95_deg"]):>8s} {fmt(st["max_deg"]):>8s} '
            f'{fmt(st["share_not_ok"], "{:.0%}"):>7s} '
            f'{fmt(st["sigma_calibration"], "{:.2f}"):>9s}  '
            + ', '.join(f'{s} {c:.3f}' for c, s in top)
        )
    hi = SIGMA_BAND[1]
    for cond, per in result['conditions'].items():
        bad = [
            f'{m} {st["sigma_calibration"]:.3g}'
            for m, st in per.items()
            if st['sigma_band'] == 'overconfident'
        ]
        if bad:
            print(f'sigma too small (mean err^2/sigma^2 > {hi:g}) on "{cond}": ' + ', '.join(bad))
    corr = result['correction']
    if corr['methods']:
        same = corr['map_camera_is_scene_camera']
        print(
            f'tilt-corrected with the {corr["error_map"]} error map: {", ".join(corr["methods"])}'
            + ('' if same else ' (the map was made for another camera: see docs/real-skies.md)')
        )
    print(f'wrote {out / "budget.json"} and {out / "budget.png"}')
    return 0
