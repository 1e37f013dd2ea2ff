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

"""`polarization-compass replay`: a recorded field run (rosbag2) through every method, offline."""

from __future__ import annotations

from ._progress import advance_to, progress_bar
from ..errors import CompassError


def register(sub):
    p = sub.add_parser(
        'replay',
        help='process a recorded rosbag2 field run offline: errors of every method',
        description='Run every method (and the tilt correction, with --error-map) over a rosbag2 '
        "(MCAP or sqlite3) faster than real time, with the nodes' code, against the "
        "bag's reference heading. Writes replay.csv, summary.csv/.json and figures "
        "like the paper's Fig 17-22. Defaults are the nodes' shipped parameters.",
    )
    p.add_argument('bag', help='rosbag2 directory (with metadata.yaml)')
    p.add_argument('--methods', default='all', help="comma-separated methods, or 'all' (default)")
    p.add_argument(
        '--topics',
        metavar='MAPPING.yaml',
        help='topic names/types of your rig (default: config/replay_topics.yaml, as record-sim)',
    )
    p.add_argument(
        '--out', default='replay_out', metavar='DIR', help='output directory (default replay_out)'
    )
    p.add_argument(
        '--stride',
        type=int,
        default=None,
        help='every N-th sensor pixel per row/column (estimator knob; default 8 as the nodes, for '
        'the '
        'methods that have a stride)',
    )
    p.add_argument(
        '--knob',
        action='append',
        default=[],
        metavar='[METHOD.]NAME=VALUE',
        help='estimator knob for every method or one method, e.g. least_squares.weighting=uniform',
    )
    p.add_argument(
        '--prior',
        choices=('imu', 'last', 'none'),
        default='imu',
        help='what resolves the 180 deg ambiguity (heading_estimator prior_source; default imu)',
    )
    p.add_argument(
        '--error-map',
        default='default',
        metavar='MAP.npz',
        help='error map for the tilt correction (default: the map shipped with the package, as '
        'the '
        "tilt_corrector node; 'none': raw headings only)",
    )
    p.add_argument('--no-plots', action='store_true', help='CSV and summary only')
    p.add_argument(
        '--plots-every',
        type=int,
        default=0,
        metavar='N',
        help='also write the diagnostic figure (as estimate --plot) of every N-th frame to '
        'OUT/frames/ (0 = none, the default)',
    )
    p.add_argument(
        '--sky-check',
        action='store_true',
        help='check every result against the whole sky, as estimate does on real images (sigma '
        'with '
        "the frame's misfit, 180 deg side, poor_fit; ~15-30 ms per frame)",
    )
    p.add_argument(
        '--principal-point-sigma-px',
        type=float,
        default=None,
        metavar='PX',
        help="the camera calibration's 1-sigma of the principal point [px], as the "
        "heading_estimator's principal_point_sigma_px (default: 0.5 %% of the focal length, a "
        "calibration's typical one); grows every heading's sigma by the camera tilt it is "
        'equivalent to',
    )
    p.add_argument(
        '--workers',
        type=int,
        default=None,
        metavar='N',
        help='threads sharing the methods over one read of the bag (default: one per core; '
        'results do '
        'not depend on it)',
    )
    p.set_defaults(func=run)


def _parse_knobs(items, stride):
    knobs = {
        '*': {} if stride is None else {'stride': stride}
    }  # (no --stride: the nodes' 8 where it exists)
    for item in items:
        if '=' not in item:
            raise CompassError(f'--knob needs NAME=VALUE or METHOD.NAME=VALUE, got {item!r}')
        key, value = item.split('=', 1)
        method, _, name = key.rpartition('.')
        knobs.setdefault(method or '*', {})[name] = _value(value)
    return knobs


def _value(text: str):
    t = text.strip()
    if t.lower() in ('true', 'false'):
        return t.lower() == 'true'
    if t.lower() in ('none', 'null', ''):
        return None
    for conv in (int, float):
        try:
            return conv(t)
        except ValueError:
            pass
    if ',' in t:
        return tuple(_value(x) for x in t.split(','))
    return t


def run(args) -> int:
    from ..bag import load_topic_map
    from ..replay import default_error_map, replay_bag, ReplayConfig, write_outputs

    if args.stride is not None:  # as the knob declares it, before the bag is read
        from ..pipeline.methods import check_stride

        check_stride(args.stride, ())
    if args.plots_every < 0:
        raise CompassError(f'--plots-every must be >= 0, got {args.plots_every}')
    if args.workers is not None and not 1 <= args.workers <= 64:
        raise CompassError(f'--workers must be in [1, 64], got {args.workers}')
    methods = (
        ()
        if args.methods.strip() == 'all'
        else tuple(m.strip() for m in args.methods.split(',') if m.strip())
    )
    error_map, note = args.error_map, None
    if error_map == 'none':
        error_map = None
    elif error_map == 'default':
        error_map = default_error_map()
        if error_map is None:
            note = (
                'no error map shipped with this build: corrected headings are not computed (give '
                '--error-map)'
            )
    config = ReplayConfig(
        methods=methods,
        knobs=_parse_knobs(args.knob, args.stride),
        prior_source=args.prior,
        error_map=error_map,
        sky_check=args.sky_check,
        principal_point_sigma_px=args.principal_point_sigma_px,
    )
    tm = load_topic_map(args.topics)
    with progress_bar('replay', ' frames') as bar:
        result = replay_bag(
            args.bag, config, tm, lambda k: advance_to(bar, k), workers=args.workers
        )
    paths = write_outputs(result, args.out, args.bag, plots=not args.no_plots)
    if args.plots_every:
        from ..replay_figures import write_frame_figures

        figs = write_frame_figures(args.bag, result, tm, config, args.plots_every, args.out)
        paths['frame_figures'] = f'{len(figs)} in {args.out}/frames'
    print(
        f'{args.bag}: {result.frames} frames, {result.bag_duration_s:.1f} s of recording in '
        f'{result.wall_s:.1f} s '
        f'({result.speed_x_real_time:.1f}x real time; {result.cpu_s:.1f} s of CPU in '
        f'{result.workers} '
        f'thread(s), {result.speed_x_real_time_cpu:.1f}x on one idle core)'
    )
    if note:
        print(f'note: {note}')
    for line in result.plan.problems:
        print(f'note: {line}')
    for line in result.tally.lines():
        print(f'  {line}')
    print(
        f'{"stream":28s} {"count":>6s} {"mean":>8s} {"rms":>8s} {"p95":>8s} {"max":>8s} '
        f'{"missed":>6s}'
    )
    for name, s in result.summary.items():
        print(
            f'{name:28s} {s["count"]:6d} {s["mean"]:8.3f} {s["rms"]:8.3f} {s["p95"]:8.3f} '
            f'{s["max"]:8.3f} '
            f'{s["missed"]:6d}'
        )
    for k, p in paths.items():
        print(f'wrote {p}')
    return 0
