"""The node executables as separate processes on real DDS (loopback only): simulator -> estimator ->
corrector -> evaluator with the shipped parameter files. Checks topics against graphs.py, rates,
message contents (ENU yaw = 90 - bearing, unit quaternion, covariance layout) and level-camera
accuracy against the truth computed here from the motion profile (not read from the simulator)."""
import json
import math

import numpy as np
import pytest
from test_nodes_helpers import CONFIG, SMALL_SCENE, Proc, Recorder, no_traceback, node_env, quat, stamp

pytestmark = [pytest.mark.ros, pytest.mark.slow]

START_NS = 1_573_797_600_000_000_000          # 2019-11-15T06:00:00Z, the simulator's default start
START_BEARING, RATE_DEG_S, FRAME_HZ, N_FRAMES = 10.0, 36.0, 10.0, 20


def test_sim_graph_on_dds(ros_env, tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import CameraInfo, Image, Imu
    from std_msgs.msg import Float64, String

    from polarization_compass import graphs
    from polarization_compass.nodes import topics as T

    env = node_env(ros_env)
    scene = tmp_path / "small.yaml"
    scene.write_text(SMALL_SCENE)
    report = tmp_path / "report"
    logs = tmp_path / "logs"
    m = "least_squares"
    tm = T.method_topics(m)
    rec = Recorder(int(env["ROS_DOMAIN_ID"]))
    for topic, ty in ((T.TRUTH, Imu), (tm["heading_raw"], Imu), (tm["heading"], Imu), (tm["bearing_raw"], Float64),
                      (tm["status"], String), (T.IMU, Imu), (T.CAMERA_INFO, CameraInfo), (T.IMAGE, Image),
                      (T.CLOCK, Clock), (T.DIAGNOSTICS, DiagnosticArray), (T.EVAL_SUMMARY, String)):
        rec.sub(ty, topic)
    sim_time = ["-p", "use_sim_time:=true"]
    procs = [
        Proc("heading_estimator_least_squares", "heading_estimator",
             ["--params-file", str(CONFIG / "heading_estimator.yaml"), "-p", f"method:={m}", "-p", "knob.stride:=4",
              *sim_time], env, logs),
        Proc("tilt_corrector_least_squares", "tilt_corrector",
             ["--params-file", str(CONFIG / "tilt_corrector.yaml"), "-p", f"method:={m}", "-p", "correction:=none",
              *sim_time], env, logs),
        Proc("error_evaluator", "error_evaluator",
             ["--params-file", str(CONFIG / "error_evaluator.yaml"), "-p", f"methods:=[{m}]",
              "-p", "direct_methods:=['']", "-p", f"report_dir:={report}", *sim_time], env, logs),
    ]
    sim = Proc("sky_simulator", "sky_simulator",
               ["--params-file", str(CONFIG / "sky_simulator.yaml"), "-p", f"scene:={scene}", "-p", "encoding:=32FC1",
                "-p", "pitch_deg:=0.0", "-p", f"start_bearing_deg:={START_BEARING}",
                "-p", f"turn_rate_deg_s:={RATE_DEG_S}", "-p", f"duration_s:={N_FRAMES / FRAME_HZ}",
                "-p", f"rate_hz:={FRAME_HZ}", "-p", "wait_for_subscribers:=2", "-p", "exit_when_done:=true",  # estimator + recorder
                "-p", "linger_s:=1.0", "-p", "wait_timeout_s:=60.0"], env, logs)
    try:
        # the nodes' actual topics equal graphs.py's declaration (checked while they run)
        got_first = rec.spin_until(lambda: len(rec.msgs[tm["heading_raw"]]) >= 1, 90, procs + [sim])
        assert got_first, "no heading arrived"
        g = graphs.build("sim", {"methods": m, "tilt_aware": "false"})
        builtin = {"/rosout", "/parameter_events", "/clock"}
        for name in ("heading_estimator_least_squares", "tilt_corrector_least_squares", "error_evaluator"):
            spec = g.node(name)
            pubs, subs = rec.node_topics(name)
            want_pubs = dict((t, (ty,)) for t, ty in spec.resolved_publishes())
            want_subs = dict((t, (ty,)) for t, ty in spec.resolved_subscribes())
            assert {k: v for k, v in pubs.items() if k not in builtin} == want_pubs, name
            assert {k: v for k, v in subs.items() if k not in builtin} == want_subs, name
        assert sim.wait(timeout=120) == 0, sim.stderr
        rec.spin_for(1.0)
        codes = {p.name: p.stop() for p in procs}
    finally:
        for p in procs + [sim]:
            if p.alive():
                p.stop()
        rec.spin_for(0.2)
        rec.close()
    assert codes == {p.name: 0 for p in procs}, {p.name: p.stderr[-1500:] for p in procs}
    for p in procs + [sim]:
        assert no_traceback(p.stderr), p.stderr

    # ---------------------------------------------------------------- truth, independently
    truth = rec.msgs[T.TRUTH]
    stamps = [stamp(msg) for _, msg in truth]
    assert len(truth) == N_FRAMES
    assert np.array_equal(np.diff(stamps), np.full(N_FRAMES - 1, 100_000_000)) and stamps[0] == START_NS
    true_bearing = {s: (START_BEARING + RATE_DEG_S * (s - START_NS) / 1e9) % 360.0 for s in stamps}
    for _, msg in truth:
        yaw = 2 * math.atan2(quat(msg)[2], quat(msg)[3])
        assert math.remainder(math.degrees(yaw) - (90.0 - true_bearing[stamp(msg)]), 360) == pytest.approx(0, abs=1e-9)

    # ---------------------------------------------------------------- the heading: form and accuracy
    raw = rec.msgs[tm["heading_raw"]]
    assert [stamp(msg) for _, msg in raw] == stamps, "frames dropped or reordered"
    bearings = [msg.data for _, msg in rec.msgs[tm["bearing_raw"]]]
    assert len(bearings) == N_FRAMES
    errors = []
    for (_, msg), b in zip(raw, bearings):
        q = quat(msg)
        assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-12) and q[0] == 0.0 and q[1] == 0.0
        yaw_deg = math.degrees(2 * math.atan2(q[2], q[3]))
        assert math.remainder(yaw_deg - (90.0 - b), 360.0) == pytest.approx(0.0, abs=1e-9)   # ENU yaw = 90 - bearing
        c = np.asarray(msg.orientation_covariance).reshape(3, 3)
        assert c[0, 0] == c[1, 1] == 1000.0 and 0 < c[2, 2] < math.radians(1.0) ** 2
        assert np.count_nonzero(c - np.diag(np.diag(c))) == 0
        assert msg.angular_velocity_covariance[0] == -1.0 and msg.linear_acceleration_covariance[0] == -1.0
        assert msg.header.frame_id == "base_link"
        errors.append(math.remainder(b - true_bearing[stamp(msg)], 360.0))
    assert max(abs(e) for e in errors) < 0.05, errors                      # level camera
    st = rec.statuses(tm["status"])
    assert len(st) == N_FRAMES and all(s["status"] == "ok" and s["published"] for s in st)
    corrected = rec.msgs[tm["heading"]]                                   # correction none: pass-through
    assert [stamp(msg) for _, msg in corrected] == stamps
    assert all(np.allclose(quat(a), quat(b), atol=1e-9) for (_, a), (_, b) in zip(raw, corrected))

    # ---------------------------------------------------------------- camera, IMU, clock, rates
    images = rec.msgs[T.IMAGE]
    assert [stamp(msg) for _, msg in images] == stamps
    im = images[0][1]
    assert (im.encoding, im.width, im.height, im.step) == ("32FC1", 612, 512, 612 * 4)
    assert im.header.frame_id == "camera_optical_frame"
    info = rec.msgs[T.CAMERA_INFO][0][1]
    assert info.k[0] == pytest.approx(4.0 / 13.8e-3) and info.k[2] == pytest.approx(305.5)
    imu = rec.msgs[T.IMU]
    imu_stamps = np.array([stamp(msg) for _, msg in imu])
    assert np.all(np.diff(imu_stamps) == 20_000_000) and len(imu) >= 5 * (N_FRAMES - 1)     # 50 Hz sim time
    assert set(stamps) <= set(imu_stamps.tolist())
    clock = [stamp_ns_of_clock(msg) for _, msg in rec.msgs[T.CLOCK]]
    assert clock and np.all(np.diff(clock) >= 0) and clock[-1] >= stamps[-1]
    wall = np.array([t for t, _ in raw])
    rate = (len(wall) - 1) / (wall[-1] - wall[0])
    assert rate > 3.0, f"heading rate {rate:.1f} Hz (camera 10 Hz)"
    diag_names = {s.name.split(":")[0] for _, arr in rec.msgs[T.DIAGNOSTICS] for s in arr.status}
    assert {"heading_estimator_least_squares", "tilt_corrector_least_squares", "error_evaluator",
            "sky_simulator"} <= diag_names
    est_diag = [s for _, arr in rec.msgs[T.DIAGNOSTICS] for s in arr.status
                if s.name.startswith("heading_estimator_least_squares")][-1]
    keys = {kv.key: kv.value for kv in est_diag.values}
    assert {"rate_hz", "processing_ms_p95", "stamp_age_ms_p95", "rejected", "last_status"} <= set(keys)
    assert keys["rejected"] == "0"

    # ---------------------------------------------------------------- the evaluator's report
    s = json.loads((report / "evaluation_summary.json").read_text())
    d = s["streams"]["least_squares/raw"]
    assert s["truth_frames"] == N_FRAMES and d["count"] == N_FRAMES and d["missed"] == 0
    assert d["rms"] == pytest.approx(math.sqrt(np.mean(np.square(errors))), abs=1e-6)
    assert d["max"] == pytest.approx(max(abs(e) for e in errors), abs=1e-6)
    assert (report / "evaluation.png").is_file() and (report / "evaluation_samples.csv").is_file()
    live = json.loads(rec.msgs[T.EVAL_SUMMARY][-1][1].data)
    assert live["streams"]["least_squares/raw"]["count"] >= 1
    print(f"\nlevel camera: max |error| {max(abs(e) for e in errors):.5f} deg over {N_FRAMES} frames; "
          f"heading rate {rate:.1f} Hz wall")


def stamp_ns_of_clock(msg) -> int:
    return int(msg.clock.sec) * 1_000_000_000 + int(msg.clock.nanosec)
