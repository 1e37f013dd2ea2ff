"""Topic names and message types of every node: the single source used by the nodes themselves,
by :mod:`polarization_compass.graphs` (launch files, ``polarization-compass sim``) and by the tests.

All names are relative, so a namespace moves a whole graph and ``--ros-args -r old:=new`` remaps
any of them; ``/diagnostics`` and ``/clock`` are absolute by ROS convention. Per-method topics live
under ``compass/<method>/`` so that, with default parameters, every estimator, corrector and the
evaluator connect without remapping.

ROS-free: no rclpy import here.
"""
from __future__ import annotations

__all__ = ["IMAGE", "ARRAY", "T_FLOAT32_MULTIARRAY", "CAMERA_INFO", "IMU", "TRUTH", "FIX", "CLOCK", "DIAGNOSTICS", "EVAL_SUMMARY", "FRAMES", "IMU_DEPTH",
           "method_topics", "simulator_topics", "estimator_topics", "corrector_topics", "evaluator_topics",
           "evaluator_streams",
           "T_IMAGE", "T_CAMERA_INFO", "T_IMU", "T_FIX", "T_CLOCK", "T_DIAG", "T_STRING", "T_FLOAT64",
           "T_QUAT_STAMPED"]

# message types (ROS interface names)
T_IMAGE = "sensor_msgs/msg/Image"
T_CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
T_IMU = "sensor_msgs/msg/Imu"
T_FIX = "sensor_msgs/msg/NavSatFix"
T_CLOCK = "rosgraph_msgs/msg/Clock"
T_DIAG = "diagnostic_msgs/msg/DiagnosticArray"
T_STRING = "std_msgs/msg/String"
T_FLOAT64 = "std_msgs/msg/Float64"
T_QUAT_STAMPED = "geometry_msgs/msg/QuaternionStamped"
T_FLOAT32_MULTIARRAY = "std_msgs/msg/Float32MultiArray"

IMAGE = "camera/image_raw"              # the polarization mosaic, as a camera driver publishes it
CAMERA_INFO = "camera/camera_info"
ARRAY = "compass_array/intensities"     # photodiode-array readings, units x channels (docs/photodiode-arrays.md)
IMU = "imu/data"                        # attitude of base_link in ENU (roll/pitch used)
TRUTH = "ground_truth/heading"          # simulator only: true heading, same Imu form as the estimate
FIX = "gps/fix"                         # site (latitude/longitude/altitude)
ATTITUDE_IN = "sim/attitude"            # simulator input when attitude_source = topic
CLOCK = "/clock"
DIAGNOSTICS = "/diagnostics"
EVAL_SUMMARY = "evaluation/summary"     # JSON running statistics per stream
FRAMES = "sim/frames"                   # simulator: JSON {stamp_ns, wall_ns} per image (wall-clock latency)

#: History depth of the IMU subscriptions. They are best effort (REP-2003 sensor-data QoS: a best-effort
#: reader matches both reliable and best-effort writers, a reliable reader only reliable ones) and deep
#: enough for 2 s of a 100 Hz IMU, so that samples arriving while a long callback runs are kept.
IMU_DEPTH = 200


def method_topics(method: str) -> dict:
    """Per-method topic names."""
    base = f"compass/{method}"
    return {
        "heading_raw": f"{base}/heading_raw",          # Imu, estimator output (not tilt-corrected)
        "bearing_raw": f"{base}/bearing_raw_deg",      # Float64, same, true bearing in degrees
        "status": f"{base}/status",                    # String (JSON), one per image, also failures
        "heading": f"{base}/heading",                  # Imu, corrector output (what to fuse)
        "bearing": f"{base}/bearing_deg",              # Float64
        "correction_status": f"{base}/correction_status",
    }


def simulator_topics(attitude_source: str = "motion", publish_clock: bool = True, attitude_input_type: str = "imu",
                     array: bool = False):
    """(publishes, subscribes): lists of (topic, type). ``array``: also a photodiode-array compass."""
    pubs = [(IMAGE, T_IMAGE), (CAMERA_INFO, T_CAMERA_INFO), (IMU, T_IMU), (TRUTH, T_IMU), (FIX, T_FIX),
            (FRAMES, T_STRING), (DIAGNOSTICS, T_DIAG)]
    if array:
        pubs.append((ARRAY, T_FLOAT32_MULTIARRAY))
    if publish_clock:
        pubs.append((CLOCK, T_CLOCK))
    subs = []
    if attitude_source == "topic":
        subs.append((ATTITUDE_IN, T_IMU if attitude_input_type == "imu" else T_QUAT_STAMPED))
    return pubs, subs


def estimator_topics(method: str, site_source: str = "parameters", needs_tilt: bool = False,
                     prior_source: str = "none", input_kind: str = "image"):
    t = method_topics(method)
    pubs = [(t["heading_raw"], T_IMU), (t["bearing_raw"], T_FLOAT64), (t["status"], T_STRING),
            (DIAGNOSTICS, T_DIAG)]
    subs = [(ARRAY, T_FLOAT32_MULTIARRAY)] if input_kind == "array" else [(IMAGE, T_IMAGE), (CAMERA_INFO, T_CAMERA_INFO)]
    if site_source == "navsatfix":
        subs.append((FIX, T_FIX))
    if needs_tilt or prior_source == "imu":
        subs.append((IMU, T_IMU))
    return pubs, subs


def corrector_topics(method: str, site_source: str = "parameters"):
    t = method_topics(method)
    pubs = [(t["heading"], T_IMU), (t["bearing"], T_FLOAT64), (t["correction_status"], T_STRING),
            (DIAGNOSTICS, T_DIAG)]
    subs = [(t["heading_raw"], T_IMU), (IMU, T_IMU)]
    if site_source == "navsatfix":
        subs.append((FIX, T_FIX))
    return pubs, subs


def evaluator_streams(methods, include_raw: bool = True, include_corrected: bool = True,
                      direct_methods=()) -> list[tuple[str, str]]:
    """(stream name, topic) pairs: ``<method>/raw`` and ``<method>/corrected`` for each method, and
    ``<method>/raw`` only for methods in ``direct_methods`` (no corrector, e.g. tilt_aware)."""
    out = []
    for m in methods:
        t = method_topics(m)
        if include_raw or m in direct_methods:
            out.append((f"{m}/raw", t["heading_raw"]))
        if include_corrected and m not in direct_methods:
            out.append((f"{m}/corrected", t["heading"]))
    return out


def evaluator_topics(streams, latency_source: str = "sim_frames"):
    pubs = [(EVAL_SUMMARY, T_STRING), (DIAGNOSTICS, T_DIAG)]
    subs = [(TRUTH, T_IMU), (DIAGNOSTICS, T_DIAG)] + [(topic, T_IMU) for _, topic in streams]
    if latency_source == "sim_frames":
        subs.append((FRAMES, T_STRING))
    for name, _ in streams:                       # statuses: why a frame was not published
        method, kind = name.split("/")
        subs.append((method_topics(method)["status" if kind == "raw" else "correction_status"], T_STRING))
    return pubs, subs
