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
`polarization-compass errormap`: sweep heading errors to a map.

The sweep runs over sun altitude x yaw x pitch x roll, in this process or on Dask distributed; the
map is an .npz, NetCDF 3 or a Zarr store.
"""

from __future__ import annotations

import json
import re
import sys

from ..errors import CompassError

#: Lets ``--yaw -180:180:5`` parse: argparse otherwise takes a leading '-' for an option unless the
#: word looks like a plain negative number (``--yaw=-180:180:5`` works everywhere regardless).
RANGE_ARG_MATCHER = re.compile(r'^-\d+$|^-\d*\.\d+$|^-\d*\.?\d*(:-?\d*\.?\d*)+$')


def allow_negative_ranges(parser) -> None:
    parser._negative_number_matcher = RANGE_ARG_MATCHER  # noqa: SLF001 - see RANGE_ARG_MATCHER


def register(sub):
    p = sub.add_parser(
        'errormap',
        help='heading error of each method over sun altitude x yaw x pitch x roll',
        description='Render the scene with the sun at azimuth 0 (so the camera bearing is the '
        "paper's yaw psi) "
        'at every grid cell, run each method on the pixels it reads, and store '
        'error_deg[method, sun altitude, yaw, pitch, roll] = fold(estimated psi - true psi) in '
        '(-90, 90]. Ranges are A:B:STEP, inclusive, or one value. Cells with |pitch|+|roll| > 30 '
        'are skipped, except the grid nodes interpolation inside that region reads '
        '(--support); --full-domain computes them all. Chunks run on Dask: an embedded '
        'LocalCluster on '
        'all cores, or an existing cluster with --scheduler. Interrupt at any time: finished '
        'chunks '
        'are kept in the Zarr store OUT.partial.zarr (or OUT itself for .zarr) and the same '
        'command resumes.',
    )
    _add_grid_options(p)
    _add_run_options(p)
    _add_domain_and_output_options(p)
    allow_negative_ranges(p)
    p.set_defaults(func=run)


def _add_grid_options(p) -> None:
    """Add what is swept: scene or array, methods, and the four axes."""
    p.add_argument(
        '--scene', help="scene YAML: sky model, noise, lens (default: the paper's set-up)"
    )
    p.add_argument(
        '--array-geometry',
        metavar='G.yaml',
        help='map a photodiode-array compass with this geometry instead of the camera (mounted '
        'like '
        "the camera; the scene's photodiode_array noise/brightness apply); methods: those that "
        'run on units',
    )
    p.add_argument('--methods', default='all', help='all, or a comma-separated list of methods')
    p.add_argument('--sun-altitude', required=True, metavar='A:B:STEP', help='sun altitudes, deg')
    p.add_argument(
        '--yaw', required=True, metavar='A:B:STEP', help='yaw psi (= camera bearing here), deg'
    )
    p.add_argument(
        '--pitch', required=True, metavar='A:B:STEP', help='pitch (about camera x), deg'
    )
    p.add_argument('--roll', required=True, metavar='A:B:STEP', help='roll (about camera y), deg')


def _add_run_options(p) -> None:
    """Add how the cells are computed: stride, workers, Dask scheduler."""
    p.add_argument(
        '--stride',
        type=int,
        help='methods with a stride knob read every N-th sensor pixel '
        '(default: the sweep sampling, see docs/error-maps.md)',
    )
    p.add_argument(
        '--workers',
        type=int,
        help='LocalCluster worker processes (default: all cores; 1 runs in '
        'this process, without Dask)',
    )
    p.add_argument(
        '--scheduler',
        metavar='tcp://HOST:PORT',
        help='run on this existing Dask cluster (dask scheduler / dask worker) instead of a '
        'LocalCluster',
    )


def _add_domain_and_output_options(p) -> None:
    """Add the tilt domain, the storage and the output map."""
    p.add_argument(
        '--full-domain', action='store_true', help='also compute cells with |pitch|+|roll| > 30'
    )
    p.add_argument(
        '--tilt-limit', type=float, default=30.0, help='the |pitch|+|roll| limit, deg (default 30)'
    )
    p.add_argument(
        '--support',
        type=int,
        default=2,
        choices=(0, 1, 2),
        help='grid steps computed beyond the limit: 2 for cubic interpolation (default), '
        '1 for multilinear, 0 none',
    )
    p.add_argument(
        '--float32', action='store_true', help='store error_deg as float32 (half the file)'
    )
    p.add_argument(
        '--restart', action='store_true', help='discard the Zarr store of an earlier run'
    )
    p.add_argument('--no-progress', action='store_true', help='no progress bar')
    p.add_argument(
        '--out',
        required=True,
        help='output map: .npz (what the nodes ship), .nc (one NetCDF 3 '
        'file) or .zarr (the labelled Zarr store itself)',
    )


def parse_methods(text: str) -> list[str]:
    from ..estimators import estimator_names

    known = estimator_names()
    if text.strip() == 'all':
        return known
    names = [m.strip() for m in text.split(',') if m.strip()]
    if not names:
        raise CompassError('--methods is empty')
    unknown = [m for m in names if m not in known]
    if unknown:
        raise CompassError(f'unknown method(s) {", ".join(unknown)}; known: {", ".join(known)}')
    if len(set(names)) != len(names):
        raise CompassError('--methods lists a method twice')
    return names


def run(args) -> int:
    from ..sweep import run_sweep
    from ..sweep_spec import parse_range, SweepSpec

    methods = _selected_methods(args)
    axes = {
        'sun_altitude_deg': parse_range(args.sun_altitude, 'sun-altitude', -90, 90),
        'yaw_deg': parse_range(args.yaw, 'yaw', -360, 720),
        'pitch_deg': parse_range(args.pitch, 'pitch', -89, 89),
        'roll_deg': parse_range(args.roll, 'roll', -180, 180),
    }
    _check_options(args, methods)
    spec = SweepSpec(
        methods,
        scene=_scene(args),
        knobs=_stride_knobs(methods, args.stride),
        full_domain=args.full_domain,
        tilt_limit_deg=args.tilt_limit,
        support=args.support,
        array=bool(args.array_geometry),
        **axes,
    )
    if spec.cell_count() == 0:
        raise CompassError(
            'no cell to compute: every (pitch, roll) is outside the tilt limit (use --full-domain)'
        )
    m = run_sweep(
        spec,
        out=args.out,
        workers=args.workers,
        progress=not args.no_progress,
        resume=not args.restart,
        float32=args.float32,
        scheduler=args.scheduler,
    )
    json.dump(_summary(m, args.out), sys.stdout)
    sys.stdout.write('\n')
    return 0


def _selected_methods(args) -> list[str]:
    """Read ``--methods``: camera methods, or a photodiode array's with ``--array-geometry``."""
    if args.array_geometry:
        from ..photodiode.heading import array_methods

        if args.methods.strip() == 'all':
            return list(array_methods())
    return parse_methods(args.methods)


def _check_options(args, methods) -> None:
    """Check the options that are not sweep axes (the stride by its knob declaration)."""
    import math

    from ..sweep import OUTPUT_SUFFIXES

    if args.stride is not None:
        from ..pipeline.methods import check_stride

        check_stride(args.stride, () if args.array_geometry else methods)
    if args.workers is not None and not (1 <= args.workers <= 256):
        raise CompassError(f'--workers must be in [1, 256], got {args.workers}')
    if not (math.isfinite(args.tilt_limit) and 0 <= args.tilt_limit <= 180):
        raise CompassError(f'--tilt-limit must be in [0, 180], got {args.tilt_limit}')
    if not str(args.out).endswith(OUTPUT_SUFFIXES):
        raise CompassError(f'--out must name a {", ".join(OUTPUT_SUFFIXES)} map, got {args.out!r}')
    if args.scheduler is not None and not re.match(r'^(tcp|tls|ws|wss)://\S+$', args.scheduler):
        raise CompassError(
            f'--scheduler must be a network address like tcp://HOST:PORT (or tls://, ws://, '
            f'wss://), got {args.scheduler!r}; inproc:// lives inside one process and ucx:// '
            'needs UCX-Py'
        )


def _scene(args):
    """Load the scene; with ``--array-geometry`` its photodiode array takes that geometry."""
    from ..scene_load import load_scene

    scene = load_scene(args.scene)
    if not args.array_geometry:
        return scene
    from ..scene_load import scene_from_dict

    if args.stride:
        raise CompassError('--stride has no meaning for a photodiode array')
    return scene_from_dict(
        {
            **scene.to_dict(),
            'photodiode_array': {
                **(scene.photodiode_array or {}),
                'geometry': args.array_geometry,
            },
        }
    )


def _stride_knobs(methods, stride) -> dict:
    """Give the methods that have a stride knob their sweep knobs with ``stride`` (zenith none)."""
    knobs = {}
    if stride:
        from ..estimators import EstimatorError, make_estimator, registry

        for m in methods:
            want = {**registry.sweep_knobs(m), 'stride': stride}
            try:
                make_estimator(m, **want)
            except EstimatorError:
                continue
            knobs[m] = want
    return knobs


def _summary(m, out) -> dict:
    """Summarise the written map: shape, methods, cells, time and each method's largest error."""
    import numpy as np

    v = m.valid
    return {
        'out': str(out),
        'shape': list(m.shape),
        'methods': list(m.methods),
        'cells_estimated': m.meta['cells_estimated'],
        'valid_cells': int(v.sum()),
        'elapsed_s': m.meta['elapsed_s_last_run'],
        'workers': m.meta['workers'],
        'max_abs_error_deg': {
            name: float(np.abs(m.error_deg[i][v[i]]).max()) if v[i].any() else None
            for i, name in enumerate(m.methods)
        },
    }
