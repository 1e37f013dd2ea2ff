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
Record-sim + offline replay: a recorded field run through the nodes' code.

Independent checks: the paper-imager tilt error curve of the physics notes (section 3, computed
there without this code) comes out of a bag; the reference and truth follow the motion profile's
closed form; tilt_aware is exact under Rayleigh (notes section 3); corrupt messages are counted by
reason exactly as planted; both storage formats give identical numbers.
"""

import dataclasses
import datetime as dt
import json
import math
from pathlib import Path
import re

import numpy as np
from polarization_compass import bag as B
from polarization_compass.camera import CameraModel
from polarization_compass.conventions import camera_attitude_from_body_quat, CameraAttitude
from polarization_compass.recording import record_sim, RecordSpec
from polarization_compass.replay import (
    FramePipeline,
    iter_synced_frames,
    replay_bag,
    ReplayConfig,
)
from polarization_compass.scene_load import load_scene
import pytest

ROOT = Path(__file__).resolve().parents[1]
NANJING = (32.026778, 118.853306, 30.0)
# the paper's imager (Table 1: 2448 x 2048 x 3.45 um, f 4 mm) with 96 x 80 big pixels: same field
# of view
PAPER_FOV_SMALL = CameraModel(
    width_px=96,
    height_px=80,
    focal_length_mm=4.0,
    pixel_pitch_x_um=2448 * 3.45 / 96,
    pixel_pitch_y_um=2048 * 3.45 / 80,
)
# notes section 3: least squares, pitch -20, sun altitude 20, psi = -180, -150, ..., 180
NOTES_PITCH20_ALT20 = [0, 2.0, 4.5, 7.1, 8.3, 6.0, 0, -6.0, -8.3, -7.1, -4.5, -2.0, 0]


def _time_at_altitude(target_deg):
    """
    Return the UTC time and azimuth when the sun is nearest ``target_deg`` high.

    UTC time on 15 Nov 2019 afternoon (Nanjing) when the sun is nearest ``target_deg`` high, and
    its azimuth.
    """
    from polarization_compass.solar import sun_position

    base = np.datetime64('2019-11-15T04:00')
    times = base + np.arange(0, 300).astype('timedelta64[m]')
    p = sun_position(times, *NANJING)
    k = int(np.argmin(np.abs(p.altitude_deg - target_deg)))
    t = dt.datetime(2019, 11, 15, 4, 0, tzinfo=dt.timezone.utc) + dt.timedelta(minutes=k)
    return t, float(p.altitude_deg[k]), float(p.azimuth_deg[k])


def _scene(camera=PAPER_FOV_SMALL, t=None, bearing=0.0):
    s = load_scene(None).replace(camera=camera, attitude=CameraAttitude(bearing, 0.0, 0.0))
    return s.replace(time_utc=t) if t is not None else s


@pytest.fixture(scope='module')
def alt20(tmp_path_factory):
    """
    Record a 36-frame turn at pitch -20 with the sun 20 deg high.

    The turn starts at psi = 0, with no IMU/reference noise.
    """
    t, alt, az = _time_at_altitude(20.0)
    out = tmp_path_factory.mktemp('alt20')
    runs = {}
    for storage in ('mcap', 'sqlite3'):
        spec = RecordSpec(
            duration_s=3.6,
            rate_hz=10.0,
            storage=storage,
            imu_attitude_noise_deg=0.0,
            reference_noise_deg=0.0,
        )
        runs[storage] = record_sim(_scene(t=t, bearing=az), spec, out / storage)
    return runs, alt, az


def _replay(path, workers=1, **kw):
    cfg = {'knobs': {'*': {'stride': 1}}}
    cfg.update(kw)
    return replay_bag(path, ReplayConfig(**cfg), workers=workers)


# ------------------------------------------------------------------------------------------------
# record-sim
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_record_sim_writes_what_a_rig_records(alt20, storage):
    runs, _, az = alt20
    summary = runs[storage]
    path = Path(summary['bag'])
    start = summary['start_ns']
    assert summary['frames'] == 36
    with B.BagReader(path) as r:
        topics = r.topics()
        assert topics['/camera/image_raw'] == ('sensor_msgs/msg/Image', 36)
        assert topics['/camera/camera_info'] == ('sensor_msgs/msg/CameraInfo', 36)
        assert topics['/ground_truth/heading'] == ('sensor_msgs/msg/Imu', 36)
        assert (
            topics['/imu/data'][0] == 'sensor_msgs/msg/Imu' and topics['/imu/data'][1] >= 50 * 3.5
        )
        assert (
            topics['/gps/fix'][0] == 'sensor_msgs/msg/NavSatFix'
            and 4 <= topics['/gps/fix'][1] <= 7
        )
        last_log = 0
        for topic, mtype, log_ns, raw in r.messages(list(topics)):
            assert log_ns >= last_log  # receive-time order
            last_log = log_ns
            msg = B.deserialize(raw, mtype)
            t = B.stamp_ns(msg.header)
            assert log_ns > t  # received after it was stamped
            if topic == '/camera/image_raw':
                k = round((t - start) / 1e8)
                assert t == start + k * 10**8
                m = B.decode_mosaic(msg)
                assert msg.encoding == 'mono16' and m.shape == (80, 96) and 0 < m.max() <= 4095
            elif topic == '/ground_truth/heading':
                # reference = the motion's closed form: bearing = start + 360 deg * t / duration
                want = (az + 360.0 * (t - start) / 3.6e9) % 360.0
                b = camera_attitude_from_body_quat(B.decode_orientation(msg)).bearing_deg
                assert math.remainder(b - want, 360.0) == pytest.approx(0.0, abs=1e-6)
                assert (
                    msg.header.frame_id == 'base_link' and msg.angular_velocity_covariance[0] == -1
                )
            elif topic == '/imu/data':
                att = camera_attitude_from_body_quat(B.decode_orientation(msg))
                assert att.pitch_deg == pytest.approx(
                    -20.0, abs=1e-6
                ) and att.roll_deg == pytest.approx(0, abs=1e-6)
            elif topic == '/gps/fix':
                assert B.decode_navsatfix(msg) == pytest.approx(NANJING)


def test_record_sim_refuses_a_fixed_sun_and_a_run_without_frames(tmp_path):
    s = _scene().replace(sun_fixed=(180.0, 30.0))
    with pytest.raises(Exception, match='ephemeris'):
        record_sim(s, RecordSpec(duration_s=1.0), tmp_path / 'a')
    with pytest.raises(Exception, match='no frame'):
        record_sim(_scene(), RecordSpec(duration_s=0.05, rate_hz=10.0), tmp_path / 'b')
    assert not (tmp_path / 'a').exists() and not (tmp_path / 'b').exists()


# ------------------------------------------------------------------------------------------------
# replay against independent numbers
# ------------------------------------------------------------------------------------------------
def test_replay_reproduces_the_notes_tilt_error_curve(alt20):
    runs, alt, _ = alt20
    assert alt == pytest.approx(20.0, abs=0.1)
    res = _replay(runs['mcap']['bag'], methods=('least_squares', 'tilt_aware'))
    ls = [r for r in res.rows if r.method == 'least_squares']
    ta = [r for r in res.rows if r.method == 'tilt_aware']
    assert len(ls) == len(ta) == 36 and all(r.status == 'ok' for r in ls + ta)
    err = np.array([r.raw_error_deg for r in ls])  # psi = 0, 10, ..., 350 deg
    # psi = 30 k for k = 0..11 against the notes' psi = -180 + 30 j: magnitudes (the sign
    # convention of the notes' curve is the opposite one, see the lead's preamble) and antisymmetry
    ours = err[::3]
    notes = {(-180 + 30 * j) % 360: v for j, v in enumerate(NOTES_PITCH20_ALT20)}
    for k, e in enumerate(ours):
        assert abs(e) == pytest.approx(abs(notes[30 * k]), abs=0.15), (30 * k, e)
    np.testing.assert_allclose(err[1:], -err[1:][::-1], atol=0.05)  # err(psi) = -err(-psi)
    # exact tilt compensation under Rayleigh (notes 3). Not exactly 0 here: a 12-bit superpixel
    # demosaic of 1.1 deg pixels (up to 0.1 deg on 2 of 36 frames, the same without any bag: the
    # front end on the mosaic)
    ta_err = np.abs([r.raw_error_deg for r in ta])
    assert np.median(ta_err) < 0.002 and ta_err.max() < 0.15
    # reference interpolated at image stamps = the motion's truth (no reference noise)
    truth = runs['mcap']['truth']
    for r in ls:
        assert math.remainder(r.reference_bearing_deg - truth[r.stamp_ns], 360) == pytest.approx(
            0, abs=1e-6
        )
    s = res.summary['least_squares/raw']
    assert s['count'] == 36 and s['max'] == pytest.approx(np.abs(err).max())
    assert s['rms'] == pytest.approx(math.sqrt(np.mean(err**2)))


@pytest.fixture(scope='module')
def small_map(tmp_path_factory):
    """
    Build an error map of least squares for the test camera around the alt20 run.

    The map comes from errormap's own sweep.
    """
    from polarization_compass.sweep import run_sweep, SweepSpec

    out = tmp_path_factory.mktemp('map') / 'map.npz'
    spec = SweepSpec(
        methods=('least_squares',),
        sun_altitude_deg=np.array([18.0, 22.0]),
        yaw_deg=np.arange(-180.0, 180.0, 20.0),
        pitch_deg=np.array([-22.0, -18.0]),
        roll_deg=np.array([-2.0, 2.0]),
        scene=_scene(),
        full_domain=True,
        knobs={'least_squares': {'stride': 2}},
    )  # superpixel spacing, as the replay reads
    run_sweep(spec, out=out, workers=1, progress=False)
    return out


def test_error_map_correction_removes_the_tilt_error(alt20, small_map, tmp_path):
    runs, _, _ = alt20
    res = _replay(
        runs['sqlite3']['bag'], methods=('least_squares', 'tilt_aware'), error_map=str(small_map)
    )
    s = res.summary
    assert set(s) == {
        'least_squares/raw',
        'least_squares/corrected',
        'tilt_aware/raw',
    }  # tilt_aware is direct
    assert s['least_squares/raw']['rms'] > 5.0 and s['least_squares/raw']['max'] > 8.0
    assert (
        s['least_squares/corrected']['count'] == 36 and s['least_squares/corrected']['rms'] < 0.05
    )
    ls = [r for r in res.rows if r.method == 'least_squares']
    assert all(r.correction_status == 'ok' for r in ls)
    for r in ls:  # corrected error = corrected - reference, independently of the evaluator
        assert r.corrected_error_deg == pytest.approx(
            math.remainder(r.corrected_bearing_deg - r.reference_bearing_deg, 360.0), abs=1e-9
        )
    from polarization_compass.replay import write_outputs

    paths = write_outputs(res, tmp_path / 'o')
    assert paths['plot_corrected'].stat().st_size > 10_000
    # outside the map's tilt domain nothing is guessed: out_of_domain, not published, not evaluated
    t, _, az = _time_at_altitude(20.0)
    record_sim(
        _scene(t=t, bearing=az), RecordSpec(duration_s=0.5, pitch_deg=-10.0), tmp_path / 'p10'
    )
    res2 = _replay(tmp_path / 'p10', methods=('least_squares',), error_map=str(small_map))
    assert [r.correction_status for r in res2.rows] == ['out_of_domain'] * 5
    assert (
        res2.summary['least_squares/corrected']['count'] == 0
        and res2.summary['least_squares/raw']['count'] == 5
    )


def test_worker_threads_give_the_single_thread_result(alt20, small_map):
    """
    Worker threads give the single-thread result.

    Methods split over two threads (one read of the bag feeding both) and corrected afterwards:
    every row field, every statistic and the match order equal the one-thread replay's.
    """
    runs, _, _ = alt20
    kw = {
        'methods': ('zenith', 'least_squares', 'tilt_aware', 'symmetry'),
        'error_map': str(small_map),
    }
    one = _replay(runs['mcap']['bag'], workers=1, **kw)
    two = _replay(runs['mcap']['bag'], workers=2, **kw)
    assert (one.workers, two.workers) == (1, 2)
    fields = [f.name for f in dataclasses.fields(one.rows[0])]
    assert [[getattr(r, f) for f in fields] for r in two.rows] == [
        [getattr(r, f) for f in fields] for r in one.rows
    ]
    assert two.summary == one.summary and two.matches == one.matches
    assert two.frames == one.frames == 36 and two.bag_duration_s == one.bag_duration_s
    assert two.tally.lines() == one.tally.lines()
    ls = [r for r in two.rows if r.method == 'least_squares']
    assert len(ls) == 36 and all(
        r.correction_status == 'ok' for r in ls
    )  # corrected, not left pending


def test_a_failing_worker_thread_raises_instead_of_hanging(alt20, monkeypatch):
    """
    A failing worker thread raises instead of hanging.

    An exception in a method group's thread reaches the caller (the reader is not left blocked on a
    full queue, the threads are joined), and a failure in the calling thread's group does too.
    """
    import threading

    from polarization_compass import replay as rp

    runs, _, _ = alt20
    real = rp.FramePipeline.process

    def boom_on(method):
        def process(self, frame):
            if method in self.methods and frame.stamp_ns > 0:
                raise RuntimeError(f'kernel failure in {method}')
            return real(self, frame)

        return process

    before = threading.active_count()
    for method in ('symmetry', 'zenith'):  # the other thread's group, then the calling thread's
        groups = rp.method_groups(['zenith', 'symmetry'], 2)
        assert [method] in groups
        monkeypatch.setattr(rp.FramePipeline, 'process', boom_on(method))
        with pytest.raises(RuntimeError, match=f'kernel failure in {method}'):
            _replay(runs['mcap']['bag'], workers=2, methods=('zenith', 'symmetry'))
        assert threading.active_count() == before
    monkeypatch.setattr(rp.FramePipeline, 'process', real)


def test_method_groups_partition_the_methods_by_cost():
    from polarization_compass.replay import method_groups

    ms = ['zenith', 'sm_asm', 'symmetry', 'least_squares', 'tilt_aware']
    for workers in (1, 2, 3, 5, 8):
        groups = method_groups(ms, workers)
        assert len(groups) == min(workers, len(ms))
        assert sorted(m for g in groups for m in g) == sorted(ms)  # each method exactly once
        for g in groups:  # the given order within a group
            assert g == [m for m in ms if m in g]
    two = method_groups(ms, 2)
    assert {'sm_asm', 'symmetry'} not in [set(g) for g in two]  # the two costly ones apart
    assert method_groups(['least_squares'], 4) == [['least_squares']]


def test_a_worker_group_without_the_shared_knob_still_runs(alt20):
    """
    A worker group without the shared knob still runs.

    zenith has no stride knob: alone in a worker's group, the "*" stride must not make it an
    unknown knob (the whole method set was checked once); with five workers every method has a
    group of its own.
    """
    runs, _, _ = alt20
    five = _replay(
        runs['mcap']['bag'],
        workers=5,
        methods=('zenith', 'least_squares'),
        knobs={'*': {'stride': 2}},
    )
    one = _replay(
        runs['mcap']['bag'],
        workers=1,
        methods=('zenith', 'least_squares'),
        knobs={'*': {'stride': 2}},
    )
    assert five.workers == 2 and [r.raw_bearing_deg for r in five.rows] == [
        r.raw_bearing_deg for r in one.rows
    ]
    with pytest.raises(Exception, match='unknown knob'):  # a typo is still refused up front
        _replay(
            runs['mcap']['bag'],
            workers=5,
            methods=('zenith', 'least_squares'),
            knobs={'*': {'strid': 2}},
        )


def test_missing_error_map_is_one_clear_error(alt20, tmp_path):
    runs, _, _ = alt20
    with pytest.raises(Exception, match='does not exist: make one with'):
        _replay(runs['mcap']['bag'], error_map=str(tmp_path / 'none.npz'))


def test_mcap_and_sqlite3_bags_give_identical_results(alt20):
    runs, _, _ = alt20
    a = _replay(runs['mcap']['bag'], methods=('least_squares',))
    b = _replay(runs['sqlite3']['bag'], methods=('least_squares',))

    def key(res):
        return [
            (r.stamp_ns, r.method, r.status, r.raw_bearing_deg, r.raw_error_deg) for r in res.rows
        ]

    assert key(a) == key(b) and len(a.rows) == 36


def test_shared_observation_equals_the_node_path(alt20):
    """
    The shared observation equals the node path.

    Replay demosaics once for methods with the same front end; the node calls front.estimate per
    method. Same numbers.
    """
    from polarization_compass.pipeline import HeadingFrontEnd

    runs, _, _ = alt20
    tm = B.default_topic_map()
    cfg = ReplayConfig(knobs={'*': {'stride': 4}})
    pipe = FramePipeline(cfg, tm)
    with B.BagReader(runs['mcap']['bag']) as r:
        frames = list(iter_synced_frames(r, tm, B.Tally()))[:5]
    for f in frames:
        rows = {x.method: x for x in pipe.process(f)}
        for m in pipe.methods:
            node = HeadingFrontEnd(m, cfg.knobs_for(m))
            tilt = f.tilt
            res = node.estimate(
                f.mosaic,
                f.camera,
                rows[m].sun_azimuth_deg,
                rows[m].sun_altitude_deg,
                tilt.pitch_deg if m == 'tilt_aware' else None,
                tilt.roll_deg if m == 'tilt_aware' else None,
                tilt.bearing_deg,
            )
            assert (
                res.status.value == rows[m].status and res.bearing_deg == rows[m].raw_bearing_deg
            )


def test_reference_on_its_own_epochs_is_interpolated_to_image_stamps(tmp_path):
    t, _, az = _time_at_altitude(30.0)
    spec = RecordSpec(
        duration_s=2.0, rate_hz=10.0, reference_rate_hz=7.0, reference_noise_deg=0.0, turns=0.25
    )
    summary = record_sim(
        _scene(
            camera=CameraModel(width_px=32, height_px=24, focal_length_mm=0.04), t=t, bearing=az
        ),
        spec,
        tmp_path / 'b',
    )
    res = _replay(tmp_path / 'b', methods=('least_squares',))
    truth = summary['truth']
    d = [math.remainder(r.reference_bearing_deg - truth[r.stamp_ns], 360) for r in res.rows]
    # 45 deg/s turn, 7 Hz: samples 6.4 deg apart; nlerp of a rotation about one axis errs < 0.01
    # deg there
    assert len(d) == 20 and np.abs(d).max() < 0.01
    assert res.tally.balanced()


def test_a_reference_that_stops_early_is_never_held(tmp_path):
    """
    A reference that stops early is never held.

    Issue 18: a reference stopping early (GNSS dropout, interrupted record-sim) was held for
    max_gap_s.reference past its last sample: corrected RMS 4.95 deg instead of 0.12. Now a frame
    has a reference only at an exact stamp or between samples on both sides within the gap; the
    others are counted as no_reference_near_stamp. Reference on its own 7 Hz epochs, dropped after
    1.0 s and between 0.4 and 0.7 s; the robot turns 45 deg/s, so a held value would be degrees
    off.
    """
    t, _, az = _time_at_altitude(30.0)
    spec = RecordSpec(
        duration_s=2.0, rate_hz=10.0, reference_rate_hz=7.0, reference_noise_deg=0.0, turns=0.25
    )
    summary = record_sim(
        _scene(
            camera=CameraModel(width_px=32, height_px=24, focal_length_mm=0.04), t=t, bearing=az
        ),
        spec,
        tmp_path / 'b',
    )
    t0 = min(summary['truth'])
    kept = []

    def edit(role, k, mtype, raw, log_ns):
        if role == 'reference':
            st = B.stamp_ns(B.deserialize(raw, mtype).header) - t0
            if st > 1_000_000_000 or 400_000_000 < st < 700_000_000:
                return []
            kept.append(st)
        return [(raw, log_ns)]

    _copy_bag(tmp_path / 'b', tmp_path / 'cut', edit)
    res = _replay(tmp_path / 'cut', methods=('least_squares',))
    truth = summary['truth']
    ref_ns = [t0 + s for s in kept]
    for r in res.rows:
        before = [s for s in ref_ns if s <= r.stamp_ns]
        after = [s for s in ref_ns if s >= r.stamp_ns]
        # independent of the code: a reference exists iff samples bracket the stamp within 0.25 s
        expect = bool(
            before
            and after
            and r.stamp_ns - before[-1] <= 250_000_000
            and after[0] - r.stamp_ns <= 250_000_000
        )
        assert (r.reference_bearing_deg is not None) == expect, (
            r.stamp_ns - t0,
            before[-1:],
            after[:1],
        )
        if expect:
            assert abs(math.remainder(r.reference_bearing_deg - truth[r.stamp_ns], 360)) < 0.01
    n_without = sum(r.reference_bearing_deg is None for r in res.rows)
    assert n_without >= 12  # 1.0 s .. 1.9 s (10 frames) and the 0.4 .. 0.7 s gap (2+)
    assert (
        res.tally.to_dict()['/camera/image_raw']['notes']['no_reference_near_stamp'] == n_without
    )
    assert res.tally.balanced()


# ------------------------------------------------------------------------------------------------
# robustness
# ------------------------------------------------------------------------------------------------
def _copy_bag(src, dst, edit, storage='mcap', extra=()):
    """
    Copy a bag message by message through ``edit``.

    ``edit(role, k, msg_or_raw, log_ns)`` returns a list of (raw_bytes, log_ns) to write (empty:
    drop). ``k`` counts messages per role.
    """
    tm = B.default_topic_map()
    counts = {}
    with B.BagReader(src) as r, B.BagWriter(dst, tm, storage=storage) as w:
        for topic, mtype, log_ns, raw in r.messages(list(r.topics())):
            role = tm.role_of_topic(topic)
            k = counts.get(role, 0)
            counts[role] = k + 1
            for data, t in edit(role, k, mtype, raw, log_ns):
                w.write_raw(role, data, t)


def _ser(msg, mtype):
    return B.typestore().serialize_cdr(msg, mtype)


@pytest.fixture(scope='module')
def clean(tmp_path_factory):
    t, _, az = _time_at_altitude(30.0)
    out = tmp_path_factory.mktemp('clean') / 'bag'
    spec = RecordSpec(
        duration_s=2.0, rate_hz=10.0, imu_attitude_noise_deg=0.0, reference_noise_deg=0.0
    )
    record_sim(
        _scene(
            camera=CameraModel(width_px=48, height_px=40, focal_length_mm=0.06), t=t, bearing=az
        ),
        spec,
        out,
    )
    return out


def test_corrupt_messages_are_counted_by_reason_and_the_rest_is_processed(clean, tmp_path):
    IMG = 'sensor_msgs/msg/Image'

    def edit(role, k, mtype, raw, log_ns):
        if role == 'image' and k == 3:
            return [(b'\x00\x01\x00\x00' + b'\xff' * 40, log_ns)]  # bad CDR
        if role == 'image' and k == 5:
            m = B.deserialize(raw, IMG)
            m.encoding = 'rgb8'
            return [(_ser(m, IMG), log_ns)]  # wrong encoding
        if role == 'image' and k == 7:
            m = B.deserialize(raw, IMG)
            m.data = m.data[:-10]
            return [(_ser(m, IMG), log_ns)]  # wrong size
        if role == 'image' and k == 9:
            return [(raw, log_ns), (raw, log_ns + 1000)]  # duplicate
        if role == 'imu' and k in (10, 11):
            m = B.deserialize(raw, mtype)
            m.orientation.x = float('nan')
            return [(_ser(m, mtype), log_ns)]  # NaN
        if role == 'navsatfix' and k == 1:
            m = B.deserialize(raw, mtype)
            m.status.status = -1
            return [(_ser(m, mtype), log_ns)]  # no fix
        if role == 'camera_info' and k == 2:
            m = B.deserialize(raw, mtype)
            m.distortion_model = 'kannala_brandt'
            return [(_ser(m, mtype), log_ns)]  # unknown lens model
        return [(raw, log_ns)]

    _copy_bag(clean, tmp_path / 'bad', edit)
    good = _replay(clean, methods=('least_squares', 'tilt_aware'))
    bad = _replay(tmp_path / 'bad', methods=('least_squares', 'tilt_aware'))
    d = bad.tally.to_dict()
    assert d['/camera/image_raw']['skipped'] == {
        'bad_cdr': 1,
        'bad_encoding': 1,
        'bad_size': 1,
        'duplicate_stamp': 1,
    }
    assert d['/camera/image_raw']['read'] == 21 and d['/camera/image_raw']['used'] == 17
    assert d['/imu/data']['skipped'] == {'non_finite': 2}
    assert d['/gps/fix']['skipped'] == {'no_fix': 1}
    assert d['/camera/camera_info']['skipped'] == {'unsupported_camera': 1}
    assert 'SerdeError' in d['/camera/image_raw']['first_reason']['bad_cdr']
    assert bad.tally.balanced() and good.tally.balanced()
    assert bad.frames == 17
    # every frame that survived gives exactly what the clean bag gives
    clean_rows = {(r.stamp_ns, r.method): r for r in good.rows}
    for r in bad.rows:
        g = clean_rows[(r.stamp_ns, r.method)]
        # (the IMU samples dropped as NaN change the interpolated tilt of one frame in the last
        # bits)
        assert r.status == g.status and r.raw_bearing_deg == pytest.approx(
            g.raw_bearing_deg, abs=1e-9
        )
        assert r.raw_error_deg == pytest.approx(g.raw_error_deg, abs=1e-9)


def test_out_of_order_stamps_and_receive_order_are_handled(clean, tmp_path):
    held = {}

    def edit(role, k, mtype, raw, log_ns):
        if role == 'image' and k == 4:  # image 4 arrives after image 5
            held['img'] = raw
            return []
        if role == 'image' and k == 5:
            return [(raw, log_ns), (held['img'], log_ns + 1000)]
        if role == 'imu' and k == 20:  # an IMU sample arrives 0.2 s late
            held['imu'] = (raw, log_ns)
            return []
        if role == 'imu' and k == 30:
            return [(raw, log_ns), (held['imu'][0], log_ns + 1000)]
        return [(raw, log_ns)]

    _copy_bag(clean, tmp_path / 'ooo', edit)
    good = _replay(clean, methods=('tilt_aware',))
    res = _replay(tmp_path / 'ooo', methods=('tilt_aware',))
    d = res.tally.to_dict()
    assert d['/camera/image_raw']['notes'].get('out_of_order') == 1
    assert d['/imu/data']['notes'].get('out_of_order') == 1
    assert res.tally.balanced() and res.frames == 20
    assert [(r.stamp_ns, r.raw_bearing_deg) for r in res.rows] == [
        (r.stamp_ns, r.raw_bearing_deg) for r in good.rows
    ]


def test_missing_imu_and_reference_are_explained_not_fatal(clean, tmp_path):
    _copy_bag(
        clean,
        tmp_path / 'noimu',
        lambda role, k, mt, raw, t: [] if role in ('imu', 'reference') else [(raw, t)],
    )
    res = _replay(tmp_path / 'noimu', methods=('least_squares', 'tilt_aware'), prior_source='none')
    text = ' '.join(res.plan.problems)
    assert 'imu: none on /imu/data' in text and 'reference: none on /ground_truth/heading' in text
    ta = [r for r in res.rows if r.method == 'tilt_aware']
    assert len(ta) == 20 and all(r.status == 'bad_input' and 'IMU' in r.reason for r in ta)
    ls = [r for r in res.rows if r.method == 'least_squares']
    assert len(ls) == 20 and all(
        r.raw_bearing_deg is not None and r.raw_error_deg is None for r in ls
    )
    assert res.summary['least_squares/raw']['count'] == 0
    assert res.tally.to_dict()['/camera/image_raw']['notes'] == {
        'no_imu_near_stamp': 20,
        'no_reference_near_stamp': 20,
    }


def test_a_sparse_imu_gives_the_prior_as_the_estimator_node_does(tmp_path):
    """
    A sparse IMU gives the prior as the estimator node does.

    IMU at 1 Hz, images at 10 Hz: only the images on a whole second have an IMU sample within the
    0.05 s tilt tolerance (tilt_aware runs on those only), but every image has an IMU yaw within
    the node's prior_max_age_s (2 s), so every image gets the IMU prior. The IMU's yaw is biased by
    +5 deg (counter-clockwise): the prior is the true bearing - 5 deg at the last IMU sample (the
    next one has not arrived when the image is processed, as on the node) or interpolated towards
    the image stamp, so at 9 deg/s it trails the truth - 5 by between 0 and 9 deg/s x the time
    since the last sample.
    """
    t, _, az = _time_at_altitude(30.0)
    t = t.replace(second=0, microsecond=0)
    spec = RecordSpec(
        duration_s=2.0,
        rate_hz=10.0,
        turns=0.05,
        imu_rate_hz=1.0,
        imu_attitude_noise_deg=0.0,
        imu_yaw_noise_deg=0.0,
        imu_yaw_bias_deg=5.0,
        reference_noise_deg=0.0,
    )
    run = record_sim(
        _scene(
            camera=CameraModel(width_px=48, height_px=40, focal_length_mm=0.06), t=t, bearing=az
        ),
        spec,
        tmp_path / 'bag',
    )
    res = _replay(tmp_path / 'bag', methods=('least_squares', 'tilt_aware'))
    truth = run['truth']
    assert len(truth) == 20
    for r in res.rows:
        assert r.prior_bearing_deg is not None, (r.method, r.stamp_ns)
        lag = math.remainder(r.prior_bearing_deg - (truth[r.stamp_ns] - 5.0), 360.0)
        since_sample_s = (r.stamp_ns % 1_000_000_000) / 1e9
        assert -9.0 * since_sample_s - 0.01 <= lag <= 0.01, (r.stamp_ns, lag)
    on_second = {st for st in truth if st % 1_000_000_000 == 0}
    assert len(on_second) == 2
    for r in res.rows:
        if r.method == 'tilt_aware':
            assert (r.status == 'bad_input') == (r.stamp_ns not in on_second), (
                r.stamp_ns,
                r.status,
                r.reason,
            )


def test_missing_fix_uses_the_mappings_site_or_fails_in_one_line(clean, tmp_path):
    _copy_bag(
        clean,
        tmp_path / 'nofix',
        lambda role, k, mt, raw, t: [] if role == 'navsatfix' else [(raw, t)],
    )
    with pytest.raises(B.BagError) as ei:
        _replay(tmp_path / 'nofix')
    assert 'no NavSatFix on /gps/fix' in str(ei.value) and '\n' not in str(ei.value)
    m = tmp_path / 'm.yaml'
    m.write_text('site: {latitude_deg: 32.026778, longitude_deg: 118.853306, altitude_m: 30.0}\n')
    res = replay_bag(
        tmp_path / 'nofix',
        ReplayConfig(methods=('least_squares',), knobs={'*': {'stride': 1}}),
        B.load_topic_map(m),
    )
    good = _replay(clean, methods=('least_squares',))
    assert [(r.stamp_ns, r.raw_bearing_deg) for r in res.rows] == [
        (r.stamp_ns, r.raw_bearing_deg) for r in good.rows
    ]


def test_wrong_type_on_a_mapped_topic_is_reported_and_counted(clean, tmp_path):
    m = tmp_path / 'm.yaml'
    m.write_text(
        'topics:\n  reference: {topic: /ground_truth/heading, type: '
        'geometry_msgs/msg/QuaternionStamped}\n'
    )
    res = replay_bag(
        clean,
        ReplayConfig(methods=('least_squares',), knobs={'*': {'stride': 1}}),
        B.load_topic_map(m),
    )
    assert any(
        'has type sensor_msgs/msg/Imu, the mapping says geometry_msgs/msg/QuaternionStamped' in p
        for p in res.plan.problems
    )
    assert res.tally.to_dict()['/ground_truth/heading']['skipped'] == {'type_mismatch': 20}
    assert res.tally.balanced()


# ------------------------------------------------------------------------------------------------
# command line
# ------------------------------------------------------------------------------------------------
class _Run:
    """A subprocess.CompletedProcess stand-in."""

    def __init__(self, returncode, stdout, stderr):
        self.returncode, self.stdout, self.stderr = returncode, stdout, stderr


def _cli_inproc(capsys, *args):
    """
    Run the same entry point in this process (no numba compile per call).

    Skipping the numba compile per call keeps the suite fast.
    """
    from polarization_compass.cli import main

    capsys.readouterr()
    rc = main([str(a) for a in args])
    out = capsys.readouterr()
    return _Run(rc, out.out, out.err)


def test_cli_record_sim_then_replay_writes_csv_summary_and_figures(tmp_path, capsys):
    scene = tmp_path / 's.yaml'
    scene.write_text(
        'camera: {width_px: 48, height_px: 40, focal_length_mm: 0.06}\n'
        "time_utc: '2019-11-15T06:00:00Z'\n"
    )
    r = _cli_inproc(
        capsys,
        'record-sim',
        '--scene',
        scene,
        '--duration',
        '1.5',
        '--out',
        tmp_path / 'run',
        '--storage',
        'sqlite3',
    )
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)['frames'] == 15
    r = _cli_inproc(
        capsys,
        'replay',
        tmp_path / 'run',
        '--methods',
        'least_squares,tilt_aware',
        '--out',
        tmp_path / 'o',
        '--knob',
        'least_squares.weighting=uniform',
        '--stride',
        '2',
    )
    assert r.returncode == 0, r.stderr
    assert '15 frames' in r.stdout and 'least_squares/raw' in r.stdout
    lines = (tmp_path / 'o' / 'replay.csv').read_text().splitlines()
    assert lines[0].startswith(
        'stamp_s,time_s,method,status,raw_bearing_deg,corrected_bearing_deg,'
        'reference_bearing_deg,raw_error_deg'
    )
    assert len(lines) == 1 + 2 * 15
    js = json.loads((tmp_path / 'o' / 'summary.json').read_text())
    assert js['frames'] == 15 and js['statistics']['tilt_aware/raw']['count'] == 15
    for png in ('errors_raw.png', 'errors_vs_bearing.png'):
        assert (tmp_path / 'o' / png).stat().st_size > 10_000


@pytest.mark.parametrize('kind', ['missing', 'text_file', 'no_images'])
def test_cli_replay_of_a_non_bag_is_one_line_exit_2(tmp_path, clean, kind, capsys):
    if kind == 'missing':
        p = tmp_path / 'nope'
    elif kind == 'text_file':
        p = tmp_path / 'x.txt'
        p.write_text('not a bag')
    else:
        p = tmp_path / 'noimg'
        _copy_bag(clean, p, lambda role, k, mt, raw, t: [] if role == 'image' else [(raw, t)])
    r = _cli_inproc(capsys, 'replay', p, '--out', tmp_path / 'o')
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and r.stderr.startswith(
        'polarization-compass replay: error:'
    )
    if kind == 'no_images':
        assert '/camera/image_raw' in r.stderr and '--topics' in r.stderr


def test_cli_custom_topic_names_round_trip(tmp_path, capsys):
    m = tmp_path / 'rig.yaml'
    m.write_text(
        'topics:\n  image: /pol/raw\n  camera_info: /pol/info\n  imu: /vectornav/imu\n'
        '  reference: {topic: /septentrio/heading, type: sensor_msgs/msg/Imu}\n  navsatfix: '
        '/septentrio/fix\n'
    )
    scene = tmp_path / 's.yaml'
    scene.write_text('camera: {width_px: 32, height_px: 24, focal_length_mm: 0.04}\n')
    assert (
        _cli_inproc(
            capsys,
            'record-sim',
            '--scene',
            scene,
            '--duration',
            '0.5',
            '--out',
            tmp_path / 'run',
            '--topics',
            m,
        ).returncode
        == 0
    )
    with B.BagReader(tmp_path / 'run') as r:
        assert set(r.topics()) == {
            '/pol/raw',
            '/pol/info',
            '/vectornav/imu',
            '/septentrio/heading',
            '/septentrio/fix',
        }
    r = _cli_inproc(
        capsys,
        'replay',
        tmp_path / 'run',
        '--topics',
        m,
        '--out',
        tmp_path / 'o',
        '--no-plots',
        '--methods',
        'tilt_aware',
        '--stride',
        '1',
    )
    assert r.returncode == 0, r.stderr
    assert '5 frames' in r.stdout


def test_default_topics_are_the_nodes_topics():
    from polarization_compass.specs import topics as T

    d = B.default_topic_map()
    assert (
        d.spec('image').topic == '/' + T.IMAGE
        and d.spec('camera_info').topic == '/' + T.CAMERA_INFO
    )
    assert d.spec('imu').topic == '/' + T.IMU and d.spec('navsatfix').topic == '/' + T.FIX
    assert d.spec('reference').topic == '/' + T.TRUTH


# ------------------------------------------------------------------------------------------------
# plumbing
# ------------------------------------------------------------------------------------------------
def test_prefetch_keeps_order_reraises_in_place_and_stops_when_closed():
    import threading

    from polarization_compass.replay import prefetched

    assert list(prefetched(iter(range(100)), depth=3)) == list(range(100))

    def failing():
        yield 1
        yield 2
        raise B.BagError('truncated')

    got = []
    with pytest.raises(B.BagError, match='truncated'):
        for x in prefetched(failing()):
            got.append(x)
    assert got == [1, 2]
    gen = prefetched(iter(range(10**6)), depth=2)
    assert next(gen) == 0
    gen.close()
    assert not any(t.name == 'bag-prefetch' and t.is_alive() for t in threading.enumerate())


def test_every_method_can_be_replayed_alone(clean, tmp_path, capsys):
    """
    Every method can be replayed alone.

    Issue 18: `replay --methods zenith` failed with "unknown knob stride" (the nodes' default
    stride was given to every method). Each registered method alone: exit 0 and one row per frame
    in replay.csv; an explicit --stride for a method without one is still refused (a typo, not a
    no-op).
    """
    import csv

    from polarization_compass.estimators import estimator_names

    for m in estimator_names():
        r = _cli_inproc(
            capsys, 'replay', clean, '--methods', m, '--out', tmp_path / m, '--no-plots'
        )
        assert r.returncode == 0, (m, r.stderr)
        with open(tmp_path / m / 'replay.csv') as fh:
            rows = list(csv.DictReader(fh))
        assert len(rows) == 20 and {row['method'] for row in rows} == {m}
    r = _cli_inproc(
        capsys, 'replay', clean, '--methods', 'zenith', '--stride', '4', '--out', tmp_path / 'z4'
    )
    assert r.returncode == 2 and 'stride' in r.stderr


def test_a_topic_with_an_extra_connection_of_another_type_uses_the_right_one(clean, tmp_path):
    """
    A topic with an extra connection of another type uses the right one.

    Issue 18: one extra publisher of another type on the image topic made replay refuse all its
    good images with a misleading listing. Now its Image connection is used, the CompressedImage
    messages are reported and counted as type_mismatch, and the result equals the clean bag's.
    """
    from rosbags.rosbag2 import Writer

    ts = B.typestore()
    out = tmp_path / 'mixed'
    with B.BagReader(clean) as r, Writer(out, version=9) as w:
        conns = {}
        for c in r._reader.connections:
            conns[c.id] = w.add_connection(c.topic, c.msgtype, typestore=ts)
        extra = w.add_connection(
            '/camera/image_raw', 'sensor_msgs/msg/CompressedImage', typestore=ts
        )
        CI = ts.types['sensor_msgs/msg/CompressedImage']
        Header, Time = ts.types['std_msgs/msg/Header'], ts.types['builtin_interfaces/msg/Time']
        k = 0
        for c, t, raw in r._reader.messages():
            w.write(conns[c.id], t, raw)
            if c.topic == '/camera/image_raw' and k < 3:
                m = CI(
                    header=Header(stamp=Time(sec=k, nanosec=0), frame_id='c'),
                    format='jpeg',
                    data=np.zeros(4, np.uint8),
                )
                w.write(extra, t + 1, ts.serialize_cdr(m, 'sensor_msgs/msg/CompressedImage'))
                k += 1
    good = _replay(clean, methods=('least_squares',))
    res = _replay(out, methods=('least_squares',))
    assert res.frames == good.frames == 20
    assert [(r.stamp_ns, r.raw_bearing_deg) for r in res.rows] == [
        (r.stamp_ns, r.raw_bearing_deg) for r in good.rows
    ]
    d = res.tally.to_dict()['/camera/image_raw']
    assert d['skipped'] == {'type_mismatch': 3} and d['read'] == 23 and res.tally.balanced()
    assert any(
        'also has 3 of type sensor_msgs/msg/CompressedImage' in p
        and '20 sensor_msgs/msg/Image' in p
        for p in res.plan.problems
    ), res.plan.problems


def _truncate_storage(bag, dst, fraction, drop_metadata=False):
    import shutil

    shutil.copytree(bag, dst)
    f = next(p for p in dst.iterdir() if p.suffix in ('.mcap', '.db3'))
    with open(f, 'r+b') as fh:
        fh.truncate(int(f.stat().st_size * fraction))
    if drop_metadata:
        (dst / 'metadata.yaml').unlink()
    return dst


@pytest.fixture(scope='module')
def clean_chunked(tmp_path_factory):
    """
    Record an MCAP bag of several 1 MiB chunks.

    The images are 320 x 240 mono16 (3 MB), with the clean bag's field of view.
    """
    t, _, az = _time_at_altitude(30.0)
    out = tmp_path_factory.mktemp('clean_chunked') / 'bag'
    spec = RecordSpec(
        duration_s=2.0, rate_hz=10.0, imu_attitude_noise_deg=0.0, reference_noise_deg=0.0
    )
    record_sim(
        _scene(
            camera=CameraModel(width_px=320, height_px=240, focal_length_mm=0.4), t=t, bearing=az
        ),
        spec,
        out,
    )
    return out


@pytest.fixture(scope='module')
def clean_sqlite(tmp_path_factory):
    t, _, az = _time_at_altitude(30.0)
    out = tmp_path_factory.mktemp('clean_sqlite') / 'bag'
    spec = RecordSpec(
        duration_s=2.0,
        rate_hz=10.0,
        imu_attitude_noise_deg=0.0,
        reference_noise_deg=0.0,
        storage='sqlite3',
    )
    record_sim(
        _scene(
            camera=CameraModel(width_px=48, height_px=40, focal_length_mm=0.06), t=t, bearing=az
        ),
        spec,
        out,
    )
    return out


@pytest.mark.parametrize(
    'storage, drop_metadata', [('mcap', False), ('mcap', True), ('sqlite3', False)]
)
def test_a_truncated_bag_is_read_up_to_the_damage_and_the_loss_is_counted(
    clean_chunked, clean_sqlite, tmp_path, storage, drop_metadata
):
    """
    A truncated bag is read up to the damage and the loss is counted.

    Issue 18: a truncated MCAP or sqlite3 file, or a recorder killed before metadata.yaml, could
    not be replayed at all. Now what precedes the damage is replayed (the same numbers as the sound
    bag for those frames), the damage is stated, and with metadata.yaml the messages lost are
    counted per topic.
    """
    src = clean_chunked if storage == 'mcap' else clean_sqlite
    bag = _truncate_storage(src, tmp_path / 'cut', 0.6, drop_metadata)
    with pytest.raises(Exception):  # rosbags alone refuses it (the symptom)
        from rosbags.rosbag2 import Reader

        with Reader(bag):
            pass
    good = _replay(src, methods=('least_squares',))
    res = _replay(bag, methods=('least_squares',))
    assert 0 < res.frames < 20
    rows = {r.stamp_ns: r.raw_bearing_deg for r in good.rows}
    assert all(rows[r.stamp_ns] == r.raw_bearing_deg for r in res.rows)
    text = ' '.join(res.plan.problems)
    assert 'damaged bag' in text
    if drop_metadata:
        assert 'no metadata.yaml' in text and 'unknown' in text
    else:
        lost = re.search(r'/camera/image_raw (\d+)', text.split('messages lost to the damage:')[1])
        assert int(lost.group(1)) == 20 - res.tally.to_dict()['/camera/image_raw']['read'], text


def test_replay_sky_check_keeps_clean_skies_ok_and_the_correction_running(alt20):
    """
    The replay's sky check keeps clean skies ok and the correction running.

    --sky-check on a pitched-20-deg simulated run: tilt_aware (given the IMU tilt) stays ok within
    3 sigma of the reference; least_squares is judged under its own level-camera model (the replay
    gives it no tilt), so its raw headings (which the tilt corrector then corrects) stay ok on this
    clean sky.
    """
    runs, _, _ = alt20
    res = _replay(
        runs['mcap']['bag'],
        methods=('least_squares', 'tilt_aware'),
        sky_check=True,
        knobs={'*': {'stride': 2}},
    )
    ta = [r for r in res.rows if r.method == 'tilt_aware']
    ls = [r for r in res.rows if r.method == 'least_squares']
    assert len(ta) == len(ls) == 36 and all(r.status == 'ok' for r in ta + ls)
    assert all(abs(r.raw_error_deg) <= 3 * r.sigma_deg + 0.2 for r in ta)
    assert max(abs(r.raw_error_deg) for r in ls) > 5.0  # the paper's tilt error is there
    assert all('sky_check' in r.reason or r.status == 'ok' for r in ls)
