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
`polarization-compass calibrate-mount`: a photodiode array's or a camera's mount tilt from turns.

The fit is :mod:`polarization_compass.mount_fit`; a camera's frames are read through ``estimate``
(:mod:`polarization_compass.camera_turns`); this command reads, reports and writes.
"""

from __future__ import annotations

import sys

import yaml


def register(sub):
    p = sub.add_parser(
        'calibrate-mount',
        help="a photodiode array's or a camera's mount pitch/roll from turns in place with an IMU",
        description='Fit the pitch and roll of the sensor on its body (shared by all turns) and '
        "one IMU yaw offset per turn, so that the sun's azimuth in the body frame turns with the "
        "IMU's yaw, and write the geometry (or CAMERA.yaml) with a 'mount:' section. An array "
        "recording needs a per-sample 'imu_yaw_rad' (counter-clockwise, any zero) and may mark "
        "its turns with 'turn_index'; with --camera each RECORDING is a turn list, a CSV with "
        'columns path (a frame estimate reads), imu_yaw_rad and optionally turn_index and '
        't_offset_s. Refuses, in one line, turns that cannot determine the mount.',
    )
    p.add_argument(
        'recordings',
        metavar='RECORDING',
        nargs='+',
        help='.npz or .csv array recordings, or with --camera turn lists (.csv)',
    )
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument('--geometry', help='photodiode array: sensor description YAML')
    src.add_argument(
        '--camera', metavar='CAMERA.yaml', help="camera: its CAMERA.yaml (the frames' camera)"
    )
    p.add_argument('--lat', type=float, required=True, help='site latitude, deg')
    p.add_argument('--lon', type=float, required=True, help='site longitude, deg')
    p.add_argument(
        '--time',
        action='append',
        required=True,
        help='UTC time of t_offset_s = 0, ISO 8601: one per recording (or one for all)',
    )
    p.add_argument('--pitch', type=float, default=0.0, help="the body's pitch, deg (default 0)")
    p.add_argument('--roll', type=float, default=0.0, help="the body's roll, deg (default 0)")
    p.add_argument('--out', required=True, help='sensor description (or CAMERA.yaml) to write')
    p.set_defaults(func=run)


def _samples(args, geometry):
    """Read the recordings into the fit's samples and what the scatter check needs."""
    from .cmd_estimate_array import sun_per_sample
    from ..errors import CompassError
    from ..mount_fit import turn_samples
    from ..photodiode.readings import load_array_recording
    from ..photodiode.stokes import fit_stokes

    parts, recs = [], []
    for i, path in enumerate(args.recordings):
        rec = load_array_recording(path)
        rec.check_against(geometry)
        if rec.imu_yaw_rad is None:
            raise CompassError(f'{path}: no imu_yaw_rad per sample (the IMU yaw is needed)')
        time = args.time[i] if len(args.time) > 1 else args.time[0]
        az, alt = sun_per_sample(time, rec.t_offset_s, rec.n_samples, args.lat, args.lon)
        turn = i * 1_000_000 + (0 if rec.turn_index is None else rec.turn_index)
        st = fit_stokes(rec.intensities, geometry)
        parts.append(
            turn_samples(st, geometry, rec.imu_yaw_rad, turn, az, alt, args.pitch, args.roll)
        )
        recs.append((rec, az, alt, turn))
    return parts, recs


def _scatter(geometry, recs, pitch, roll) -> tuple:
    """Return the within-turn heading scatter [deg] and ok count of tilt_aware on the turns."""
    import numpy as np

    from ..estimators.base import Status
    from ..mount_recordings import heading_scatter_deg
    from ..photodiode.heading import estimate_recording, make_array_estimator

    est = make_array_estimator('tilt_aware', geometry)
    b, yaw, turn, ok = [], [], [], []
    for rec, az, alt, t in recs:
        res = estimate_recording(est, rec.intensities, az, alt, pitch, roll)
        b += [r.bearing_deg if r.bearing_deg is not None else np.nan for r in res]
        ok += [r.status == Status.OK for r in res]
        yaw.append(rec.imu_yaw_rad)
        turn.append(np.broadcast_to(t, (rec.n_samples,)))
    return heading_scatter_deg(b, np.concatenate(yaw), np.concatenate(turn), ok)


def run(args) -> int:
    from ._checks import check_range
    from ..errors import CompassError
    from ..mount_recordings import fit_mount_recordings
    from ..photodiode.geometry import geometry_to_dict, load_array_geometry

    check_range('lat', args.lat, -90, 90)
    check_range('lon', args.lon, -180, 180)
    check_range('pitch', args.pitch, -60, 60)
    check_range('roll', args.roll, -60, 60)
    if len(args.time) not in (1, len(args.recordings)):
        raise CompassError(
            f'{len(args.time)} --time for {len(args.recordings)} recordings: give one per '
            'recording, or one for all'
        )
    if args.camera:
        return _run_camera(args)
    g0 = load_array_geometry(args.geometry).with_mount(None)
    parts, recs = _samples(args, g0)
    fit = fit_mount_recordings(g0, parts)
    m = fit.mount
    before = _scatter(g0, recs, args.pitch, args.roll)
    after = _scatter(g0.with_mount(m), recs, args.pitch, args.roll)
    mount = _mount_record(fit, before, after)
    with open(args.out, 'w', encoding='utf-8') as fh:
        fh.write('# written by polarization-compass calibrate-mount\n')
        yaml.safe_dump(geometry_to_dict(g0.with_mount(mount)), fh, sort_keys=False)
    _report(fit, before, after)
    return 0


def _run_camera(args) -> int:
    """Calibrate a camera's mount from turn lists; write its CAMERA.yaml with ``mount:``."""
    import numpy as np

    from .cmd_estimate_array import sun_per_sample
    from ..camera_file import load_camera_yaml
    from ..camera_turns import camera_turns, camera_yaml_with_mount, read_turn_list, turn_headings
    from ..mount import Mount
    from ..mount_recordings import fit_mount_recordings, heading_scatter_deg
    from ..pipeline.optical_centre import mount_against_optical_centre

    cf = load_camera_yaml(args.camera)  # a camera file estimate accepts, checked first
    parts, turns, suns = [], [], []
    for i, path in enumerate(args.recordings):
        tl = read_turn_list(path)
        time = args.time[i] if len(args.time) > 1 else args.time[0]
        az, alt = sun_per_sample(time, tl.t_offset_s, len(tl.paths), args.lat, args.lon)
        ct = camera_turns(tl, args.camera, az, alt, args.pitch, args.roll, turn_base=i * 1_000_000)
        parts.append(ct)
        turns.append(tl)
        suns.append((az, alt))
    fit = fit_mount_recordings(parts[0].rays, [c.samples for c in parts])
    m = fit.mount
    yaw = np.concatenate([t.imu_yaw_rad for t in turns])
    turn = np.concatenate([c.samples.turn for c in parts])
    before = heading_scatter_deg(
        np.concatenate([c.bearing_deg for c in parts]),
        yaw,
        turn,
        np.concatenate([c.ok for c in parts]),
    )
    mounted = Mount(m.pitch_deg, m.roll_deg, m.pitch_sigma_deg, m.roll_sigma_deg)
    camera_yaml_with_mount(args.camera, mounted, args.out)
    b, ok = [], []
    for tl, (az, alt) in zip(turns, suns):  # the kept file, read as estimate reads it
        bt, okt = turn_headings(tl.paths, args.out, az, alt, args.pitch, args.roll)
        b.append(bt)
        ok.append(okt)
    after = heading_scatter_deg(np.concatenate(b), yaw, turn, np.concatenate(ok))
    camera_yaml_with_mount(
        args.camera,
        _mount_record(fit, before, after),
        args.out,
    )
    _report(fit, before, after)
    check = mount_against_optical_centre(cf.camera, cf.principal_point_sigma_px, cf.mount, m)
    for line in check['lines']:
        print(line, file=sys.stderr)
    return 0


def _mount_record(fit, before, after):
    """Return the fitted Mount with what the YAML says of its calibration (arrays and cameras)."""
    from ..mount import Mount

    m = fit.mount
    record = {
        'turns': fit.turns,
        'samples': fit.samples,
        'residual_before_deg': round(before[0], 3),
        'residual_after_deg': round(after[0], 3),
        'sigma_widened_by': [round(float(v), 2) for v in fit.spread],
        'recordings_used': list(fit.used),
        'recordings_left_out': list(fit.left_out),
        'method': 'calibrate-mount: within-turn rms of tilt_aware bearing + IMU yaw',
    }
    return Mount(m.pitch_deg, m.roll_deg, m.pitch_sigma_deg, m.roll_sigma_deg, record)


def _report(fit, before, after) -> None:
    m = fit.mount
    if fit.warning:
        print(fit.warning, file=sys.stderr)
    print(
        f'mount pitch {m.pitch_deg:.2f} +- {m.pitch_sigma_deg:.2f} deg, roll {m.roll_deg:.2f} '
        f'+- {m.roll_sigma_deg:.2f} deg from {fit.turns} turn(s), {fit.samples} samples; '
        f'within-turn heading scatter {before[0]:.2f} -> {after[0]:.2f} deg '
        f'({before[1]} -> {after[1]} ok); angle rms {fit.angle_rms_before_deg:.2f} -> '
        f'{fit.angle_rms_after_deg:.2f} deg',
        file=sys.stderr,
    )
