"""Offline replay of a recorded field run (rosbag2): every method's heading, raw and tilt-corrected,
against the reference heading, faster than real time. ROS-free (reads bags with `rosbags`).

Same code as the nodes
----------------------
Per image, in the order the ``heading_estimator`` node does it: the camera from camera_info
(:func:`~polarization_compass.bag.decode_camera_info`), the sun at the image stamp for the site of the
latest NavSatFix (:class:`~polarization_compass.pipeline.SunSource`), the IMU attitude interpolated
to the stamp (:class:`~polarization_compass.pipeline.AttitudeBuffer`, same tolerance), the tilt given
to ``tilt_aware`` only and the 180 deg prior from the IMU's yaw (or the last heading), both decided by
the node's :class:`~polarization_compass.pipeline.TiltAndPrior`, and
:class:`~polarization_compass.pipeline.HeadingFrontEnd` (demosaic -> observation -> estimator). The
tilt correction is the ``tilt_corrector``'s
(:meth:`~polarization_compass.correction.TiltCorrector.correct_bearing`), and errors and statistics
are the ``error_evaluator``'s (:class:`~polarization_compass.evaluation.StampMatcher`, truth = the
reference interpolated to the image stamp). Headings only known modulo 180 deg are not evaluated, as
the nodes do not publish them. Methods that demosaic alike share one observation per frame (the front
end's own ``observation``).

Reading
-------
One pass over the bag in receive-time order. Auxiliary streams (IMU, reference, NavSatFix,
camera_info) are buffered by header stamp; an image is processed once the reader is ``lookahead_s``
of receive time past it (or at the end of the bag), so data stamped shortly after an image (and
messages that arrive out of order) are used. Memory is bounded by the images inside the look-ahead.
Every message read is accounted for (:class:`~polarization_compass.bag.Tally`): used, or skipped with
a reason; out-of-order stamps and images without IMU/reference data near their stamp are noted.
"""
from __future__ import annotations

import csv
import dataclasses
import json
import math
import time
from collections import deque
from contextlib import ExitStack, closing
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .bag import (BagError, BagReader, MessageError, Tally, TopicMap, decode_camera_info, decode_mosaic,
                  decode_navsatfix, decode_orientation, default_topic_map, deserialize, stamp_ns)
from .conventions import wrap_360_deg
from .errors import CompassError
from .estimators import registry

__all__ = ["SyncedFrame", "BagPlan", "plan_bag", "iter_synced_frames", "ReplayConfig", "FramePipeline",
           "MethodRow", "ReplayResult", "replay_bag", "write_outputs", "ReplayError", "method_groups",
           "default_workers"]


class ReplayError(CompassError):
    """Bad replay configuration."""


# ------------------------------------------------------------------------------------------------
# What the bag holds
# ------------------------------------------------------------------------------------------------
@dataclass
class BagPlan:
    """What a bag holds for each role, checked before any processing.

    ``present``: role -> message count on its topic; ``type_mismatch``: role -> type found;
    ``problems``: one-line statements of what is missing and what that means; ``fatal``: problems
    that leave nothing to compute (raised as one :class:`BagError`).
    """

    topics: dict
    present: dict
    type_mismatch: dict
    problems: list
    fatal: list


def plan_bag(reader: BagReader, topic_map: TopicMap) -> BagPlan:
    """Compare the bag's topics with the mapping."""
    topics = reader.topics()
    present, mismatch, problems, fatal = {}, {}, [], []
    for role, spec in topic_map.topics.items():
        found = topics.get(spec.topic)
        present[role] = found[1] if found else 0
        if found and found[0] != spec.type:
            mismatch[role] = found[0]
            problems.append(f"{role}: {spec.topic} has type {found[0]}, the mapping says {spec.type}: "
                            "its messages are skipped (fix the type in the topic mapping)")
    listing = ", ".join(f"{t} ({v[0].split('/')[-1]}, {v[1]})" for t, v in sorted(topics.items())) or "none"
    usable = {r: present[r] > 0 and r not in mismatch for r in present}
    if not usable["image"]:
        fatal.append(f"no {topic_map.spec('image').type} messages on the image topic {topic_map.spec('image').topic}"
                     f" (topics in the bag: {listing}); map yours with --topics")
    if not usable["camera_info"]:
        if topic_map.camera is None:
            fatal.append(f"no camera_info on {topic_map.spec('camera_info').topic} and no 'camera:' fallback in "
                         "the topic mapping: the pixels' viewing rays are unknown")
        else:
            problems.append("camera_info: none in the bag; using the mapping's 'camera:' intrinsics")
    if not usable["navsatfix"]:
        if topic_map.site is None:
            fatal.append(f"no NavSatFix on {topic_map.spec('navsatfix').topic} and no 'site:' fallback in the "
                         "topic mapping: the sun's position is unknown")
        else:
            problems.append("navsatfix: none in the bag; using the mapping's 'site:'")
    if not usable["imu"]:
        problems.append(f"imu: none on {topic_map.spec('imu').topic}: the tilt is unknown, so tilt_aware "
                        "estimates, tilt corrections and the IMU prior are not available")
    if not usable["reference"]:
        problems.append(f"reference: none on {topic_map.spec('reference').topic}: headings are computed but "
                        "their errors are not")
    return BagPlan(topics, present, mismatch, problems, fatal)


# ------------------------------------------------------------------------------------------------
# Synchronised frames
# ------------------------------------------------------------------------------------------------
@dataclass
class SyncedFrame:
    """One image with everything needed to process it at the image's stamp.

    ``tilt``: :class:`~polarization_compass.pipeline.CameraTilt` from the IMU within the mapping's
    ``max_gap_s.imu`` of the stamp (the nodes' ``imu_tolerance_s``), or None; ``imu_near``: the same
    within ``prior_max_age_s`` (its bearing, the IMU's coarse yaw, is the ``imu`` prior), or None.
    ``true_bearing_deg``: reference bearing of camera +y, [0, 360), or None.
    ``site``: (latitude_deg, longitude_deg, altitude_m). ``camera``: CameraModel.
    """

    stamp_ns: int
    log_ns: int
    mosaic: np.ndarray
    camera: object
    site: tuple
    tilt: object
    true_bearing_deg: float | None
    imu_near: object = None


def prefetched(iterable, depth: int = 8):
    """Iterate ``iterable`` in a background thread, ``depth`` items ahead.

    Reading a bag is mostly file reads and copies; the file reads release the GIL, so on a 2-core
    machine they overlap with the processing of the previous frame. Exceptions (a truncated bag) are
    re-raised here, in order; closing the generator early stops the thread.
    """
    import queue
    import threading

    q: queue.Queue = queue.Queue(maxsize=depth)
    stop = threading.Event()
    done = object()

    def run():
        try:
            for item in iterable:
                while not stop.is_set():
                    try:
                        q.put(item, timeout=0.1)
                        break
                    except queue.Full:
                        continue
                if stop.is_set():
                    return
            q.put(done)
        except BaseException as exc:  # noqa: BLE001 - handed to the consumer
            q.put(exc)

    th = threading.Thread(target=run, name="bag-prefetch", daemon=True)
    th.start()
    try:
        while True:
            item = q.get()
            if item is done:
                return
            if isinstance(item, BaseException):
                raise item
            yield item
    finally:
        stop.set()
        while th.is_alive():
            try:
                q.get_nowait()
            except queue.Empty:
                th.join(timeout=0.05)


def iter_synced_frames(reader: BagReader, topic_map: TopicMap, tally: Tally, plan: BagPlan | None = None,
                       prior_max_age_s: float = 2.0):
    """Yield :class:`SyncedFrame` for every usable image, in receive-time order (see the module doc).

    Images that cannot be processed (no camera intrinsics, size not matching camera_info, duplicate
    stamp, no site) are counted as skipped with a reason.
    """
    from .camera import CameraModel
    from .pipeline import AttitudeBuffer, camera_attitude_from_body_quat

    plan = plan or plan_bag(reader, topic_map)
    wanted = {spec.topic: role for role, spec in topic_map.topics.items() if plan.present.get(role, 0) > 0}
    keep_ns = int(max(10.0, 4 * topic_map.lookahead_s, 2 * prior_max_age_s) * 1e9)
    imu, ref = AttitudeBuffer(keep_ns), AttitudeBuffer(keep_ns)
    tol = {r: int(topic_map.max_gap_s[r] * 1e9) for r in ("imu", "reference")}
    prior_tol_ns = int(prior_max_age_s * 1e9)
    look_ns = int(topic_map.lookahead_s * 1e9)
    R_body_cam = topic_map.R_body_cam_array
    pending: deque = deque()
    seen_images: set = set()
    newest_image = newest_fix = newest_info = None
    camera = CameraModel(**topic_map.camera) if topic_map.camera is not None else None
    site = None
    if topic_map.site is not None:
        s = topic_map.site
        site = (float(s["latitude_deg"]), float(s["longitude_deg"]), float(s.get("altitude_m", 0.0)))
    image_topic = topic_map.spec("image").topic

    def release(item):
        t, log_ns, mosaic, cam, fix = item
        cam = cam if cam is not None else camera
        if cam is None:
            tally.skip(image_topic, "no_camera_info", "no usable camera_info before this image")
            return None
        if (cam.height_px, cam.width_px) != mosaic.shape:
            tally.skip(image_topic, "size_mismatch", f"image {mosaic.shape[1]}x{mosaic.shape[0]}, "
                                                     f"camera_info {cam.width_px}x{cam.height_px}")
            return None
        where = fix if fix is not None else site
        if where is None:
            tally.skip(image_topic, "no_site", "no usable NavSatFix before this image")
            return None
        tilt = imu.camera_tilt(t, tol["imu"], R_body_cam) if len(imu) else None
        near = imu.camera_tilt(t, prior_tol_ns, R_body_cam) if len(imu) else None
        if tilt is None:
            tally.note(image_topic, "no_imu_near_stamp")
        hit = ref.at(t, tol["reference"]) if len(ref) else None
        true_bearing = None
        if hit is not None:
            true_bearing = float(wrap_360_deg(camera_attitude_from_body_quat(hit[0], R_body_cam).bearing_deg))
        else:
            tally.note(image_topic, "no_reference_near_stamp")
        tally.used[image_topic] += 1
        return SyncedFrame(t, log_ns, mosaic, cam, where, tilt, true_bearing, near)

    for topic, mtype, log_ns, raw in prefetched(reader.messages(list(wanted))):
        role = wanted[topic]
        tally.read[topic] += 1
        if role in plan.type_mismatch:
            tally.skip(topic, "type_mismatch", f"{mtype} is not {topic_map.spec(role).type}")
            continue
        try:
            msg = deserialize(raw, mtype)
            t = stamp_ns(msg.header)
            if role == "image":
                value = decode_mosaic(msg)
            elif role in ("imu", "reference"):
                value = decode_orientation(msg)
            elif role == "navsatfix":
                value = decode_navsatfix(msg)
            else:
                value = decode_camera_info(msg, topic_map.pixel_pitch_um)
        except MessageError as exc:
            tally.skip(topic, exc.reason, exc.detail)
            continue
        if role == "image":
            if t in seen_images:
                tally.skip(topic, "duplicate_stamp", f"a second image stamped {t} ns")
                continue
            seen_images.add(t)
            if newest_image is not None and t < newest_image:
                tally.note(topic, "out_of_order")
            newest_image = t if newest_image is None else max(newest_image, t)
            # the camera and site as the node has them when this image arrives; refined by later
            # messages inside the look-ahead only if none had arrived yet
            pending.append([t, log_ns, value, None, None])
        else:
            buf = imu if role == "imu" else ref if role == "reference" else None
            newest = {"navsatfix": newest_fix, "camera_info": newest_info}.get(role) if buf is None \
                else buf.newest_ns
            if newest is not None and t < newest:
                tally.note(topic, "out_of_order")
            if buf is not None:
                buf.add(t, value)
            elif role == "navsatfix":
                if newest_fix is None or t >= newest_fix:
                    newest_fix = t
                    site = value
            else:
                if newest_info is None or t >= newest_info:
                    newest_info = t
                    camera = value
            tally.used[topic] += 1
        for item in pending:
            if item[3] is None and camera is not None:
                item[3] = camera
            if item[4] is None and site is not None:
                item[4] = site
        while pending and log_ns - pending[0][1] > look_ns:
            f = release(pending.popleft())
            if f is not None:
                yield f
    while pending:
        f = release(pending.popleft())
        if f is not None:
            yield f


# ------------------------------------------------------------------------------------------------
# Per-frame processing (the nodes' code)
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ReplayConfig:
    """How frames are processed; defaults are the nodes' shipped parameters (config/*.yaml).

    ``knobs``: per method estimator knobs (``{"*": {...}}`` applies to every method; the nodes ship
    ``stride: 8``). ``prior_source``: imu | last | none (heading_estimator ``prior_source``).
    ``error_map``: .npz from ``polarization-compass errormap`` for the tilt correction (None: no
    corrected headings; see :func:`default_error_map`). ``direct_methods``: methods the corrector
    does not touch (default: those whose estimator class ``needs_tilt``, e.g. tilt_aware).
    """

    methods: tuple = ()
    knobs: dict = field(default_factory=lambda: {"*": {"stride": 8}})
    demosaic: str = "superpixel"
    use_intensity: bool = False
    prior_source: str = "imu"
    prior_max_age_s: float = 2.0
    sun_model: str = "spa"
    error_map: str | None = None
    correction_sigma_deg: float = 0.1
    direct_methods: tuple = field(default_factory=lambda: registry.tilt_methods())

    def method_list(self) -> list[str]:
        from .estimators import estimator_names
        known = estimator_names()
        ms = list(self.methods) or known
        bad = [m for m in ms if m not in known]
        if bad:
            raise ReplayError(f"unknown method(s) {', '.join(bad)}; known: {', '.join(known)}")
        return ms

    def knobs_for(self, method: str) -> dict:
        """Knobs of ``method``: the ``"*"`` entries it has (zenith has no stride, for example), then
        its own entries (an unknown name there is an error of the estimator)."""
        from .estimators import estimator_knob_names
        names = estimator_knob_names(method)
        k = {n: v for n, v in self.knobs.get("*", {}).items() if n in names}
        k.update(self.knobs.get(method, {}))
        return k

    def for_methods(self, methods) -> "ReplayConfig":
        """This configuration for a subset of its methods (a worker's group): ``"*"`` keeps the knobs
        one of them has, so that :meth:`check_knobs`, already passed by the whole set, passes again."""
        from .estimators import estimator_knob_names
        names = set().union(*(estimator_knob_names(m) for m in methods))
        knobs = {k: v for k, v in self.knobs.items() if k != "*"}
        knobs["*"] = {n: v for n, v in self.knobs.get("*", {}).items() if n in names}
        return dataclasses.replace(self, methods=tuple(methods), knobs=knobs)

    def check_knobs(self) -> None:
        """A ``"*"`` knob no selected method has is a typo, not a no-op."""
        from .estimators import estimator_knob_names
        ms = self.method_list()
        known = set().union(*(estimator_knob_names(m) for m in ms))
        bad = sorted(set(self.knobs.get("*", {})) - known)
        if bad:
            raise ReplayError(f"unknown knob(s) {', '.join(bad)} for methods {', '.join(ms)}; "
                              f"known: {', '.join(sorted(known))}")


@dataclass
class MethodRow:
    """One method on one frame: the raw estimate, its tilt correction and the errors (deg).

    ``raw_error_deg``/``corrected_error_deg``: estimated minus reference bearing, wrapped to (-180, 180]
    (None when not evaluated: no reference, an ambiguous or failed estimate, no correction).
    """

    stamp_ns: int
    method: str
    status: str
    reason: str
    raw_bearing_deg: float | None
    corrected_bearing_deg: float | None
    correction_status: str
    reference_bearing_deg: float | None
    raw_error_deg: float | None
    corrected_error_deg: float | None
    sigma_deg: float | None
    pixels: int
    pitch_deg: float | None
    roll_deg: float | None
    sun_azimuth_deg: float
    sun_altitude_deg: float
    prior_bearing_deg: float | None

    CSV_FIELDS = ("stamp_s", "time_s", "method", "status", "raw_bearing_deg", "corrected_bearing_deg",
                  "reference_bearing_deg", "raw_error_deg", "corrected_error_deg", "correction_status",
                  "sigma_deg", "pixels", "pitch_deg", "roll_deg", "sun_azimuth_deg", "sun_altitude_deg",
                  "prior_bearing_deg", "reason")


class FramePipeline:
    """The nodes' per-frame chain for several methods at once (see the module docstring)."""

    def __init__(self, config: ReplayConfig, topic_map: TopicMap):
        from .demosaic import layout_from_mapping
        from .pipeline import HeadingFrontEnd, TiltAndPrior
        layout = layout_from_mapping(topic_map.mosaic)
        self.config = config
        config.check_knobs()
        self.methods = config.method_list()
        self.fronts = {m: HeadingFrontEnd(m, config.knobs_for(m), layout, layout.pol45_toward, config.demosaic,
                                          config.use_intensity) for m in self.methods}
        self.tilt_prior = {m: TiltAndPrior(m, config.prior_source, config.prior_max_age_s) for m in self.methods}
        self.sun = None
        self.corrector = None
        if config.error_map:
            self.corrector = _make_corrector(config)
        self.timing_ms: dict = {m: [] for m in self.methods}
        self.timing_ms["observation"] = []

    def _sun(self, frame: SyncedFrame):
        from .pipeline import SunSource
        if self.sun is None:
            self.sun = SunSource(*frame.site, model=self.config.sun_model)
        else:
            self.sun.set_site(*frame.site)
        return self.sun.at_ns(frame.stamp_ns)

    def process(self, frame: SyncedFrame) -> list[MethodRow]:
        from .pipeline import PipelineError
        c = self.config
        t_ns = frame.stamp_ns
        rows = []
        try:
            sun_az, sun_alt = self._sun(frame)
        except PipelineError as exc:
            return [MethodRow(t_ns, m, "bad_input", str(exc), None, None, "", frame.true_bearing_deg, None, None,
                              None, 0, None, None, 0.0, 0.0, None) for m in self.methods]
        tilt = frame.tilt
        obs_cache: dict = {}
        for m, front in self.fronts.items():
            inp = self.tilt_prior[m].inputs(t_ns, tilt, frame.imu_near)
            pitch, roll, prior = inp.pitch_deg, inp.roll_deg, inp.prior_bearing_deg
            if inp.tilt_missing:
                rows.append(MethodRow(t_ns, m, "bad_input", "no IMU sample near the image stamp (tilt unknown)",
                                      None, None, "", frame.true_bearing_deg, None, None, None, 0, None, None,
                                      sun_az, sun_alt, prior))
                continue
            key = front.observation_key(frame.camera)
            t0 = time.perf_counter()
            try:
                obs = obs_cache.get(key)
                if obs is None:
                    obs = front.observation(frame.mosaic, frame.camera, sun_az, sun_alt)
                    obs_cache[key] = obs
                    self.timing_ms["observation"].append((time.perf_counter() - t0) * 1e3)
                    t0 = time.perf_counter()
                result = front.estimator.estimate(dataclasses.replace(obs, pitch_deg=pitch, roll_deg=roll,
                                                                      prior_bearing_deg=prior))
            except CompassError as exc:
                rows.append(MethodRow(t_ns, m, "bad_input", str(exc), None, None, "", frame.true_bearing_deg,
                                      None, None, None, 0, pitch, roll, sun_az, sun_alt, prior))
                continue
            self.timing_ms[m].append((time.perf_counter() - t0) * 1e3)
            raw = result.bearing_deg if result.ok and not result.axial else None
            self.tilt_prior[m].remember(t_ns, result)
            corrected, cstatus = None, ""
            if raw is not None and m not in c.direct_methods and self.corrector is not None:
                corrected, cstatus = self.corrector(m, raw, result, tilt, sun_az, sun_alt, t_ns)
            rows.append(MethodRow(t_ns, m, result.status.value, result.reason,
                                  float(result.bearing_deg) if result.ok else None, corrected, cstatus,
                                  frame.true_bearing_deg, None, None, result.sigma_deg, result.pixels,
                                  tilt.pitch_deg if tilt is not None else None,
                                  tilt.roll_deg if tilt is not None else None, sun_az, sun_alt, prior))
        return rows


def default_error_map() -> str | None:
    """The error map shipped with the package (the ``tilt_corrector`` node's default), if there is one."""
    from .correction import default_map_path
    p = default_map_path()
    return str(p) if p.is_file() else None


def _make_corrector(config: ReplayConfig):
    """The ``tilt_corrector`` node's correction as a :class:`_Corrector`."""
    path = Path(config.error_map)
    if not path.is_file():
        raise ReplayError(f"error map {str(path)!r} does not exist: make one with `polarization-compass errormap "
                          "--methods zenith,sm_asm,symmetry,least_squares --sun-altitude 0:50:5 --yaw -180:175:5 "
                          "--pitch -30:30:5 --roll -30:30:5 --out MAP.npz`")
    return _Corrector(path)


class _Corrector:
    """``(method, raw_bearing_deg, result, tilt, sun_az, sun_alt, t_ns) -> (corrected_bearing_deg | None,
    status)``: :meth:`TiltCorrector.correct_bearing` (the node's) at the IMU's pitch/roll; a heading without
    an IMU tilt near its stamp is not corrected (``no_imu``).

    With ``defer`` on, headings are queued (status ``pending``) and :meth:`resolve` corrects them all with
    one vectorised inversion per method (:meth:`TiltCorrector.correct_bearings`, same numbers): an inversion
    costs about 8 ms whether it holds one heading or a thousand, which made correction the largest cost of
    an offline replay."""

    PENDING = "pending"

    def __init__(self, path: Path):
        self.path = path
        self._map = None
        self.correctors: dict = {}
        self.defer = False
        self.queue: list = []              # (row, method, raw, sun_az, sun_alt, pitch, roll)

    def _get(self, method):
        from .correction import TiltCorrector
        from .errormap import ErrorMapError, load_error_map
        if method not in self.correctors:
            try:
                if self._map is None:
                    self._map = load_error_map(self.path)          # once for every method's corrector
                self.correctors[method] = TiltCorrector(self._map, method)
            except ErrorMapError as exc:
                self.correctors[method] = str(exc)
        return self.correctors[method]

    def __call__(self, method, raw_bearing_deg, result, tilt, sun_az, sun_alt, t_ns):
        if tilt is None:
            return None, "no_imu"
        if self.defer:
            return None, self.PENDING          # the map is read when the queue is resolved
        cor = self._get(method)
        if isinstance(cor, str):
            return None, "no_map"
        corrected, c = cor.correct_bearing(raw_bearing_deg, sun_az, sun_alt, tilt.pitch_deg, tilt.roll_deg)
        return corrected, c.status.value

    def enqueue(self, row) -> None:
        """Queue a row whose ``correction_status`` is ``pending``."""
        self.queue.append(row)

    def resolve(self) -> None:
        """Correct every queued row in place (``corrected_bearing_deg``, ``correction_status``)."""
        by_method: dict = {}
        for row in self.queue:
            by_method.setdefault(row.method, []).append(row)
        for method, rows in by_method.items():
            cor = self._get(method)
            if isinstance(cor, str):                 # the map has no layer for this method
                for r in rows:
                    r.corrected_bearing_deg, r.correction_status = None, "no_map"
                continue
            cols = np.array([(r.raw_bearing_deg, r.sun_azimuth_deg, r.sun_altitude_deg, r.pitch_deg, r.roll_deg)
                             for r in rows], dtype=float)
            bearings, statuses = cor.correct_bearings(*cols.T)
            for r, b, st in zip(rows, bearings, statuses):
                r.corrected_bearing_deg = float(b) if st == "ok" else None
                r.correction_status = st
        self.queue = []


# ------------------------------------------------------------------------------------------------
# Threads
# ------------------------------------------------------------------------------------------------
def _openblas_handles():
    """(set, get) of every OpenBLAS loaded in this process (numpy's and scipy's), via ctypes."""
    import ctypes
    out = []
    try:
        with open("/proc/self/maps") as f:
            paths = {line.split()[-1] for line in f if "openblas" in line and ".so" in line}
    except OSError:
        return out
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for prefix in ("scipy_openblas", "openblas"):
            for suffix in ("64_", "_64_", ""):
                try:
                    setter = getattr(lib, f"{prefix}_set_num_threads{suffix}")
                    getter = getattr(lib, f"{prefix}_get_num_threads{suffix}")
                except AttributeError:
                    continue
                out.append((setter, getter))
                break
            else:
                continue
            break
    return out


class single_threaded_kernels:
    """Run numba kernels and BLAS on the calling thread only while replaying.

    After subsampling, a frame's kernels take 0.1-3 ms; waking a pool of threads for them costs more
    than it saves on a 2-core machine, and under load a parallel call waits ~20 ms for its threads
    (measured: a 0.1 ms demosaic took 20 ms with 2 numba threads while other work ran). numba's
    thread count is per calling thread; OpenBLAS's is process-wide and restored afterwards.
    """

    def __enter__(self):
        import numba
        self._numba = numba.get_num_threads()
        numba.set_num_threads(1)
        self._blas = [(s, int(g())) for s, g in _openblas_handles()]
        for s, _ in self._blas:
            s(1)
        return self

    def __exit__(self, *exc):
        import numba
        numba.set_num_threads(self._numba)
        for s, n in self._blas:
            s(n)


# ------------------------------------------------------------------------------------------------
# The whole bag
# ------------------------------------------------------------------------------------------------
@dataclass
class ReplayResult:
    rows: list
    summary: dict           # evaluator summary per stream
    tally: Tally
    plan: BagPlan
    frames: int
    bag_duration_s: float
    wall_s: float
    matches: list
    timing_ms: dict
    error_map: str | None = None
    cpu_s: float = 0.0          # CPU time of the process (all threads) while replaying
    workers: int = 1            # threads that shared the methods

    @property
    def speed_x_real_time(self) -> float:
        """Recorded seconds per wall-clock second."""
        return self.bag_duration_s / self.wall_s if self.wall_s > 0 else 0.0

    @property
    def speed_x_real_time_cpu(self) -> float:
        """Recorded seconds per CPU second: the speed on an otherwise idle core (load-independent)."""
        return self.bag_duration_s / self.cpu_s if self.cpu_s > 0 else 0.0




def method_groups(methods: list[str], workers: int) -> list[list[str]]:
    """Split ``methods`` into at most ``workers`` groups of similar cost (largest first onto the lightest
    group), each group keeping the given method order."""
    workers = max(1, min(int(workers), len(methods)))
    groups: list[list[str]] = [[] for _ in range(workers)]
    load = [0.0] * workers
    for m in sorted(methods, key=lambda m: -registry.relative_cost(m)):     # the estimator's relative_cost
        g = load.index(min(load))
        groups[g].append(m)
        load[g] += registry.relative_cost(m)
    return [[m for m in methods if m in g] for g in groups if g]


@dataclass
class _Read:
    """What the method groups made of one read of the bag (corrections still pending)."""

    rows: list                   # every group's, in no particular order
    truths: list                 # (stamp_ns, true bearing) per frame with a reference
    tally: Tally
    plan: BagPlan
    frames: int
    first_stamp: int | None
    last_stamp: int | None
    timing_ms: dict              # per method (and "observation"), every group's
    cpu_s: float                 # the process, every thread


def _replay_threads(path, config: ReplayConfig, topic_map: TopicMap, groups: list[list[str]],
                    progress=None) -> _Read:
    """Every method group in this process: the bag is read once, group 0 runs on this thread and each other
    group on a thread of its own, fed the same frames through a bounded queue (a group never lags more than
    ``_LAG`` frames). The compiled kernels release the GIL (``nogil``), so the groups' pixel work runs in
    parallel; a group's frames stay in order on one thread, so its state (the ``last`` prior) is the node's.
    Replaces one process per group, each reading the whole bag: on 2 cores reading a 10 MB image took
    ~7 ms of each process's ~22 ms per frame."""
    import queue
    import threading

    from .heap import keep_large_buffers_in_heap
    keep_large_buffers_in_heap()      # each 10 MB image read from the bag: 9.1 -> 6.8 ms of CPU (page faults)
    t_cpu = time.process_time()
    pipes = [FramePipeline(config.for_methods(g), topic_map) for g in groups]
    for pipe in pipes:
        if pipe.corrector is not None:
            pipe.corrector.defer = True
    rows: list[list[MethodRow]] = [[] for _ in groups]
    queues = [queue.Queue(maxsize=_LAG) for _ in groups[1:]]
    failures: list[BaseException] = []

    def work(k: int):
        import numba
        numba.set_num_threads(1)                # numba's thread count is per calling thread
        q = queues[k - 1]
        while True:
            frame = q.get()
            if frame is None:
                return
            if failures:
                continue                        # keep draining so that the reader never blocks
            try:
                rows[k].extend(pipes[k].process(frame))
            except BaseException as exc:  # noqa: BLE001 - re-raised on the calling thread
                failures.append(exc)

    threads = [threading.Thread(target=work, args=(k,), name=f"replay-group-{k}", daemon=True)
               for k in range(1, len(groups))]
    for th in threads:
        th.start()
    tally = Tally()
    truths: list = []
    first_stamp = last_stamp = None
    frames = 0
    try:
        with BagReader(path) as reader, single_threaded_kernels(), ExitStack() as stack:   # closing: the reader
            plan = plan_bag(reader, topic_map)                                              # threads stop too
            if plan.fatal:
                raise BagError(f"{reader.path}: " + "; ".join(plan.fatal))
            # decoding and pairing run on the reading thread too: the calling thread only processes its group
            # (3 interleaved runs each: 19.4-23.0 ms per frame against 21.6-22.5 with decoding on this thread)
            frames_in = stack.enter_context(closing(prefetched(
                iter_synced_frames(reader, topic_map, tally, plan, config.prior_max_age_s), 4)))
            for frame in frames_in:
                frames += 1
                first_stamp = frame.stamp_ns if first_stamp is None else min(first_stamp, frame.stamp_ns)
                last_stamp = frame.stamp_ns if last_stamp is None else max(last_stamp, frame.stamp_ns)
                if frame.true_bearing_deg is not None:
                    truths.append((frame.stamp_ns, frame.true_bearing_deg))
                for q in queues:
                    q.put(frame)
                rows[0].extend(pipes[0].process(frame))
                if failures:
                    raise failures[0]
                if progress is not None:
                    progress(frames)
    finally:
        for q in queues:
            q.put(None)
        for th in threads:
            th.join()
    if failures:
        raise failures[0]
    timing: dict = {"observation": []}
    for pipe in pipes:
        for key, v in pipe.timing_ms.items():
            timing.setdefault(key, []).extend(v)
    return _Read([r for group_rows in rows for r in group_rows], truths, tally, plan, frames, first_stamp,
                 last_stamp, timing, time.process_time() - t_cpu)


_LAG = 8            # frames a method group may fall behind the reader (each holds a 10 MB mosaic)


def default_workers() -> int:
    """Cores this process may run on."""
    import os
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def replay_bag(path, config: ReplayConfig | None = None, topic_map: TopicMap | None = None, progress=None,
               workers: int | None = None) -> ReplayResult:
    """Process a bag offline. Raises :class:`BagError` (one line) for a path that is not a usable bag.

    ``workers`` (default: every core) threads run the methods in groups of similar cost over one read of
    the bag (:func:`_replay_threads`; a method's frames stay in order on one thread, so its state, e.g. the
    ``last`` prior, is the node's); every pending heading is then corrected with one vectorised inversion
    per method and evaluated. The result does not depend on ``workers``."""
    from .evaluation import StampMatcher

    config = config or ReplayConfig()
    topic_map = topic_map or default_topic_map()
    config.check_knobs()
    methods = config.method_list()
    corrector = _make_corrector(config) if config.error_map else None
    groups = method_groups(methods, default_workers() if workers is None else workers)
    t_wall = time.perf_counter()
    read = _replay_threads(path, config, topic_map, groups, progress)
    order = {m: k for k, m in enumerate(methods)}
    rows = sorted(read.rows, key=lambda r: (r.stamp_ns, order[r.method]))
    matcher = StampMatcher(horizon_ns=10**18, max_pending=10**9)
    for m in methods:
        matcher.add_stream(f"{m}/raw", False)
        if m not in config.direct_methods and corrector is not None:
            matcher.add_stream(f"{m}/corrected", False)
    for stamp, bearing in read.truths:
        matcher.add_truth(stamp, bearing)
    for r in rows:
        if r.status == "ok" and r.raw_bearing_deg is not None:
            mt = matcher.add_estimate(f"{r.method}/raw", r.stamp_ns, r.raw_bearing_deg)
            if mt is not None:
                r.raw_error_deg = mt.error_deg
        if corrector is not None and r.correction_status == _Corrector.PENDING:
            corrector.enqueue(r)
    if corrector is not None:
        corrector.resolve()
    for r in rows:
        if r.corrected_bearing_deg is not None and f"{r.method}/corrected" in matcher.streams:
            mt = matcher.add_estimate(f"{r.method}/corrected", r.stamp_ns, r.corrected_bearing_deg)
            if mt is not None:
                r.corrected_error_deg = mt.error_deg
    matcher.finish()
    frames = read.frames
    duration = (read.last_stamp - read.first_stamp) / 1e9 if frames > 1 else 0.0
    if frames > 1:
        duration *= frames / (frames - 1)           # n frames cover n periods of recording
    wall = time.perf_counter() - t_wall
    return ReplayResult(rows, matcher.summary(), read.tally, read.plan, frames, duration, wall, matcher.matches,
                        read.timing_ms, config.error_map, read.cpu_s, len(groups))


# ------------------------------------------------------------------------------------------------
# Outputs
# ------------------------------------------------------------------------------------------------
def _fmt(v):
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.6f}"
    return v


def write_outputs(result: ReplayResult, out_dir, bag_path: str = "", plots: bool = True) -> dict:
    """``replay.csv`` (one row per frame and method), ``summary.csv``/``summary.json`` (the evaluator's
    statistics per stream, skip counts per topic and reason, speed) and the figures. Returns paths."""
    from .evaluation import write_summary_csv

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = result.rows[0].stamp_ns if result.rows else 0
    paths = {}
    p = out / "replay.csv"
    with p.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(MethodRow.CSV_FIELDS)
        for r in result.rows:
            w.writerow([f"{r.stamp_ns / 1e9:.9f}", f"{(r.stamp_ns - t0) / 1e9:.6f}", r.method, r.status,
                        *(_fmt(v) for v in (r.raw_bearing_deg, r.corrected_bearing_deg, r.reference_bearing_deg,
                                            r.raw_error_deg, r.corrected_error_deg)),
                        r.correction_status, _fmt(r.sigma_deg), r.pixels,
                        *(_fmt(v) for v in (r.pitch_deg, r.roll_deg, r.sun_azimuth_deg, r.sun_altitude_deg,
                                            r.prior_bearing_deg)), r.reason])
    paths["csv"] = p
    paths["summary_csv"] = write_summary_csv(out / "summary.csv", result.summary)
    statuses: dict = {}
    for r in result.rows:
        statuses.setdefault(r.method, {}).setdefault(r.status, 0)
        statuses[r.method][r.status] += 1
    js = {"bag": str(bag_path), "error_map": result.error_map, "frames": result.frames, "bag_duration_s": result.bag_duration_s,
          "wall_s": result.wall_s, "cpu_s": result.cpu_s, "speed_x_real_time": result.speed_x_real_time,
          "speed_x_real_time_cpu": result.speed_x_real_time_cpu,
          "statistics": result.summary, "statuses": statuses, "topics": result.tally.to_dict(),
          "problems": result.plan.problems,
          "timing_ms_median": {k: float(np.median(v)) for k, v in result.timing_ms.items() if v}}
    p = out / "summary.json"
    p.write_text(json.dumps(js, indent=1, default=float, allow_nan=False))
    paths["summary_json"] = p
    if plots:
        paths.update(plot_replay(result, out))
    return paths


def plot_replay(result: ReplayResult, out_dir) -> dict:
    """Figures like the paper's: error against time per method (Fig 17-19, raw) and raw vs corrected
    per method (Fig 20-22); plus the evaluator's error-against-bearing figure."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .evaluation import plot_report

    out = Path(out_dir)
    paths = {}
    rows = result.rows
    if not rows:
        return paths
    t0 = rows[0].stamp_ns
    methods = list(dict.fromkeys(r.method for r in rows))
    series = {}
    for r in rows:
        s = series.setdefault(r.method, {"t": [], "raw": [], "tc": [], "cor": []})
        if r.raw_error_deg is not None:
            s["t"].append((r.stamp_ns - t0) / 1e9)
            s["raw"].append(r.raw_error_deg)
        if r.corrected_error_deg is not None:
            s["tc"].append((r.stamp_ns - t0) / 1e9)
            s["cor"].append(r.corrected_error_deg)
    pitch = [r.pitch_deg for r in rows if r.pitch_deg is not None]
    roll = [r.roll_deg for r in rows if r.roll_deg is not None]
    tilt_txt = (f"IMU pitch {round(float(np.mean(pitch)), 1) + 0.0:.1f} deg, roll {round(float(np.mean(roll)), 1) + 0.0:.1f}"
                " deg (mean)" if pitch else "tilt unknown")
    if not any(series[m]["raw"] for m in methods):
        return paths

    fig, ax = plt.subplots(figsize=(8.0, 4.2), dpi=110)
    for m in methods:
        s = series[m]
        if s["raw"]:
            ax.plot(s["t"], s["raw"], "-", lw=1.0, marker=".", ms=2.5, label=f"{m} (rms {_rms(s['raw']):.2f})")
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xlabel("time since first image, s")
    ax.set_ylabel("heading error (estimate - reference), deg")
    ax.set_title(f"Raw heading error per method; {tilt_txt}", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    p = out / "errors_raw.png"
    fig.savefig(p)
    plt.close(fig)
    paths["plot_raw"] = p

    corrected = [m for m in methods if series[m]["cor"]]
    if corrected:
        n = len(corrected)
        fig, axes = plt.subplots(n, 1, figsize=(8.0, 2.3 * n + 0.8), dpi=110, sharex=True, squeeze=False)
        for ax, m in zip(axes[:, 0], corrected):
            s = series[m]
            ax.plot(s["t"], s["raw"], "-", lw=1.0, color="tab:red", label=f"raw (rms {_rms(s['raw']):.2f})")
            ax.plot(s["tc"], s["cor"], "-", lw=1.0, color="tab:blue", label=f"corrected (rms {_rms(s['cor']):.2f})")
            ax.axhline(0.0, color="0.5", lw=0.6)
            ax.set_ylabel(f"{m}\nerror, deg")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, loc="best")
        axes[-1, 0].set_xlabel("time since first image, s")
        fig.suptitle(f"Tilt correction with the error map; {tilt_txt}", fontsize=9)
        fig.tight_layout()
        p = out / "errors_corrected.png"
        fig.savefig(p)
        plt.close(fig)
        paths["plot_corrected"] = p
    p = plot_report(out / "errors_vs_bearing.png", result.matches, title="error against reference bearing")
    if p is not None:
        paths["plot_vs_bearing"] = p
    return paths


def _rms(v) -> float:
    a = np.asarray(v, dtype=float)
    return float(math.sqrt(float(np.mean(a * a)))) if a.size else 0.0
