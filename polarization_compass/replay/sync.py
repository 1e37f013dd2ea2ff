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
Reading a bag: its plan and its images paired with the auxiliary streams.

What the bag holds (:func:`plan_bag`), and its images paired with the auxiliary streams at their
stamps (:func:`iter_synced_frames`; see :mod:`polarization_compass.replay`, "Reading").
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from ..bag.codec import (
    decode_camera_info,
    decode_navsatfix,
    decode_orientation,
    deserialize,
    stamp_ns,
)
from ..bag.errors import MessageError
from ..bag.image import decode_mosaic
from ..bag.reader import BagReader, Tally
from ..bag.topic_map import TopicMap
from ..conventions import camera_attitude_from_body_quat, wrap_360_deg
from ..pipeline.attitude_sigma import imu_tilt_variance_deg2

__all__ = ['BagPlan', 'plan_bag', 'SyncedFrame', 'prefetched', 'iter_synced_frames']


@dataclass
class BagPlan:
    """
    What a bag holds for each role, checked before any processing.

    ``present``: role -> message count of the mapped type on its topic; ``type_mismatch``: role ->
    the other type(s) found there (``|``-joined), whose messages are skipped; ``problems``:
    one-line statements of what is missing and what that means; ``fatal``: problems that leave
    nothing to compute (raised as one :class:`BagError`).
    """

    topics: dict
    present: dict
    type_mismatch: dict
    problems: list
    fatal: list


def plan_bag(reader: BagReader, topic_map: TopicMap) -> BagPlan:
    """
    Compare the bag's topics with the mapping, before any processing.

    A mapped topic whose connections have several types (e.g. one extra publisher of another
    type) is used through its connections of the mapped type; the messages of the other types are
    reported here and skipped one by one as ``type_mismatch``.

    Parameters
    ----------
    reader : BagReader
        The open bag.
    topic_map : TopicMap
        Roles, topics and types, and the fallbacks for a missing camera_info or NavSatFix.

    Returns
    -------
    BagPlan
        Message counts per role, type mismatches, problems (what is missing and what that
        means) and fatal problems (nothing to compute; the caller raises them as one
        :class:`BagError`).

    """
    types_of = reader.topic_types()
    present, mismatch, problems, fatal = {}, {}, [], []
    for role, spec in topic_map.topics.items():
        types = types_of.get(spec.topic, {})
        present[role] = types.get(spec.type, 0)
        others = {t: n for t, n in types.items() if t != spec.type}
        if others:
            mismatch[role] = '|'.join(sorted(others))
            text = ', '.join(f'{n} of type {t}' for t, n in sorted(others.items()))
            if present[role]:
                problems.append(
                    f'{role}: {spec.topic} also has {text} (another connection): those are '
                    'skipped; '
                    f'its {present[role]} {spec.type} messages are used'
                )
            else:
                problems.append(
                    f'{role}: {spec.topic} has type {mismatch[role]}, the mapping says '
                    f'{spec.type}: its '
                    'messages are skipped (fix the type in the topic mapping)'
                )
    listing = (
        ', '.join(
            f'{t} ({"|".join(x.split("/")[-1] for x in sorted(ty))}, {sum(ty.values())})'
            for t, ty in sorted(types_of.items())
        )
        or 'none'
    )
    usable = {r: present[r] > 0 for r in present}
    if not usable['image']:
        fatal.append(
            f'no {topic_map.spec("image").type} messages on the image topic '
            f'{topic_map.spec("image").topic}'
            f' (topics in the bag: {listing}); map yours with --topics'
        )
    if not usable['camera_info']:
        if topic_map.camera is None:
            fatal.append(
                f"no camera_info on {topic_map.spec('camera_info').topic} and no 'camera:' "
                'fallback in '
                "the topic mapping: the pixels' viewing rays are unknown"
            )
        else:
            problems.append(
                "camera_info: none in the bag; using the mapping's 'camera:' intrinsics"
            )
    if not usable['navsatfix']:
        if topic_map.site is None:
            fatal.append(
                f"no NavSatFix on {topic_map.spec('navsatfix').topic} and no 'site:' fallback in "
                'the '
                "topic mapping: the sun's position is unknown"
            )
        else:
            problems.append("navsatfix: none in the bag; using the mapping's 'site:'")
    if not usable['imu']:
        problems.append(
            f'imu: none on {topic_map.spec("imu").topic}: the tilt is unknown, so tilt_aware '
            'estimates, tilt corrections and the IMU prior are not available'
        )
    if not usable['reference']:
        problems.append(
            f'reference: none on {topic_map.spec("reference").topic}: headings are computed but '
            'their errors are not'
        )
    return BagPlan(reader.topics(), present, mismatch, problems, fatal)


@dataclass
class SyncedFrame:
    """
    One image with everything needed to process it at the image's stamp.

    ``tilt``: :class:`~polarization_compass.pipeline.CameraTilt` from the IMU within the mapping's
    ``max_gap_s.imu`` of the stamp (the nodes' ``imu_tolerance_s``), or None; ``imu_near``: the
    same within ``prior_max_age_s`` (its bearing, the IMU's coarse yaw, is the ``imu`` prior), or
    None. ``true_bearing_deg``: reference bearing of camera +y, [0, 360), or None. ``site``:
    (latitude_deg, longitude_deg, altitude_m). ``camera``: CameraModel. ``imu_tilt_var_deg2``:
    the tilt variance [deg^2] the latest IMU message read states
    (:func:`~polarization_compass.pipeline.attitude_sigma.imu_tilt_variance_deg2`; None: unknown),
    as the node holds it.
    """

    stamp_ns: int
    log_ns: int
    mosaic: np.ndarray
    camera: object
    site: tuple
    tilt: object
    true_bearing_deg: float | None
    imu_near: object = None
    imu_tilt_var_deg2: float | None = None


def prefetched(iterable, depth: int = 8):
    """
    Iterate ``iterable`` in a background thread, ``depth`` items ahead.

    Reading a bag is mostly file reads and copies; the file reads release the GIL, so on a 2-core
    machine they overlap with the processing of the previous frame. Closing the generator early
    stops the thread.

    Parameters
    ----------
    iterable : iterable
        The source (e.g. :meth:`BagReader.messages`).
    depth : int, default 8
        Items read ahead at most.

    Yields
    ------
    object
        The items of ``iterable``, in order.

    Raises
    ------
    BaseException
        Whatever iterating ``iterable`` raised (e.g. :class:`BagError` of a truncated bag),
        re-raised here in order.

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

    th = threading.Thread(target=run, name='bag-prefetch', daemon=True)
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


class _FrameSync:
    """
    The state of :func:`iter_synced_frames`, one step per message read.

    It holds the auxiliary streams buffered by header stamp, the latest camera and site, and the
    images waiting inside the look-ahead. A step: :meth:`decode`, then :meth:`add_image` or
    :meth:`add_aux`, then :meth:`due` releases the images the reader is ``lookahead_s`` past
    (:meth:`rest` at the end of the bag); :meth:`release` pairs one.
    """

    def __init__(self, topic_map: TopicMap, tally: Tally, plan: BagPlan, prior_max_age_s: float):
        from ..camera import CameraModel
        from ..pipeline.attitude import AttitudeBuffer

        self.topic_map, self.tally, self.plan = topic_map, tally, plan
        self.wanted = {
            spec.topic: role
            for role, spec in topic_map.topics.items()
            if plan.present.get(role, 0) > 0 or role in plan.type_mismatch
        }
        keep_ns = int(max(10.0, 4 * topic_map.lookahead_s, 2 * prior_max_age_s) * 1e9)
        self.imu, self.ref = AttitudeBuffer(keep_ns), AttitudeBuffer(keep_ns)
        self.tol = {r: int(topic_map.max_gap_s[r] * 1e9) for r in ('imu', 'reference')}
        self.prior_tol_ns = int(prior_max_age_s * 1e9)
        self.look_ns = int(topic_map.lookahead_s * 1e9)
        self.R_body_cam = topic_map.R_body_cam_array
        self.pending: deque = deque()  # [stamp_ns, log_ns, mosaic, camera | None, site | None]
        self.seen_images: set = set()
        self.newest_image = self.newest_fix = self.newest_info = None
        self.camera = CameraModel(**topic_map.camera) if topic_map.camera is not None else None
        self.site = None
        self.imu_var = None  # the latest IMU message's tilt variance [deg^2] (None: unknown)
        if topic_map.site is not None:
            s = topic_map.site
            self.site = (
                float(s['latitude_deg']),
                float(s['longitude_deg']),
                float(s.get('altitude_m', 0.0)),
            )
        self.image_topic = topic_map.spec('image').topic

    def decode(self, topic: str, role: str, mtype: str, raw):
        """
        Decode one message into (stamp_ns, value), or None when it is skipped.

        A skipped message is counted with a reason.
        """
        self.tally.read[topic] += 1
        if mtype != self.topic_map.spec(role).type:  # a connection of another type on this topic
            self.tally.skip(
                topic, 'type_mismatch', f'{mtype} is not {self.topic_map.spec(role).type}'
            )
            return None
        try:
            msg = deserialize(raw, mtype)
            t = stamp_ns(msg.header)
            if role == 'image':
                value = decode_mosaic(msg)
            elif role == 'imu':  # the attitude and the tilt variance its covariance states
                value = (
                    decode_orientation(msg),
                    imu_tilt_variance_deg2(getattr(msg, 'orientation_covariance', ())),
                )
            elif role == 'reference':
                value = decode_orientation(msg)
            elif role == 'navsatfix':
                value = decode_navsatfix(msg)
            else:
                value = decode_camera_info(msg, self.topic_map.pixel_pitch_um)
        except MessageError as exc:
            self.tally.skip(topic, exc.reason, exc.detail)
            return None
        return t, value

    def add_image(self, topic: str, t: int, log_ns: int, mosaic: np.ndarray) -> bool:
        """Queue an image; False (skipped, counted) for a second image with the same stamp."""
        if t in self.seen_images:
            self.tally.skip(topic, 'duplicate_stamp', f'a second image stamped {t} ns')
            return False
        self.seen_images.add(t)
        if self.newest_image is not None and t < self.newest_image:
            self.tally.note(topic, 'out_of_order')
        self.newest_image = t if self.newest_image is None else max(self.newest_image, t)
        # the camera and site as the node has them when this image arrives; refined by later
        # messages inside the look-ahead only if none had arrived yet
        self.pending.append([t, log_ns, mosaic, None, None])
        return True

    def add_aux(self, topic: str, role: str, t: int, value) -> None:
        """Buffer an IMU or reference attitude; the newest NavSatFix and camera_info are kept."""
        buf = self.imu if role == 'imu' else self.ref if role == 'reference' else None
        newest = (
            {'navsatfix': self.newest_fix, 'camera_info': self.newest_info}.get(role)
            if buf is None
            else buf.newest_ns
        )
        if newest is not None and t < newest:
            self.tally.note(topic, 'out_of_order')
        if role == 'imu':
            value, self.imu_var = value
        if buf is not None:
            buf.add(t, value)
        elif role == 'navsatfix':
            if self.newest_fix is None or t >= self.newest_fix:
                self.newest_fix = t
                self.site = value
        else:
            if self.newest_info is None or t >= self.newest_info:
                self.newest_info = t
                self.camera = value
        self.tally.used[topic] += 1

    def due(self, log_ns: int):
        """
        Yield the frames of queued images the reader has passed by the look-ahead.

        Fill in the camera and site of queued images that had none, then yield the frames of the
        images the reader (at receive time ``log_ns``) is more than the look-ahead past.
        """
        for item in self.pending:
            if item[3] is None and self.camera is not None:
                item[3] = self.camera
            if item[4] is None and self.site is not None:
                item[4] = self.site
        while self.pending and log_ns - self.pending[0][1] > self.look_ns:
            f = self.release(self.pending.popleft())
            if f is not None:
                yield f

    def rest(self):
        """Yield the frames of every image still queued (end of the bag)."""
        while self.pending:
            f = self.release(self.pending.popleft())
            if f is not None:
                yield f

    def release(self, item) -> SyncedFrame | None:
        """Return the :class:`SyncedFrame` of a queued image, None (counted) when it cannot be."""
        tally, imu, ref, R_body_cam = self.tally, self.imu, self.ref, self.R_body_cam
        t, log_ns, mosaic, cam, fix = item
        cam = cam if cam is not None else self.camera
        if cam is None:
            tally.skip(
                self.image_topic, 'no_camera_info', 'no usable camera_info before this image'
            )
            return None
        if (cam.height_px, cam.width_px) != mosaic.shape:
            tally.skip(
                self.image_topic,
                'size_mismatch',
                f'image {mosaic.shape[1]}x{mosaic.shape[0]}, '
                f'camera_info {cam.width_px}x{cam.height_px}',
            )
            return None
        where = fix if fix is not None else self.site
        if where is None:
            tally.skip(self.image_topic, 'no_site', 'no usable NavSatFix before this image')
            return None
        tilt = imu.camera_tilt(t, self.tol['imu'], R_body_cam) if len(imu) else None
        near = imu.camera_tilt(t, self.prior_tol_ns, R_body_cam) if len(imu) else None
        if tilt is None:
            tally.note(self.image_topic, 'no_imu_near_stamp')
        # the reference is interpolated between samples either side within max_gap_s.reference, or
        # exact at the stamp; never held from one side (a stream that stopped early would give
        # silently wrong errors)
        hit = ref.at(t, self.tol['reference'], hold=False) if len(ref) else None
        true_bearing = None
        if hit is not None:
            true_bearing = float(
                wrap_360_deg(camera_attitude_from_body_quat(hit[0], R_body_cam).bearing_deg)
            )
        else:
            tally.note(self.image_topic, 'no_reference_near_stamp')
        tally.used[self.image_topic] += 1
        return SyncedFrame(t, log_ns, mosaic, cam, where, tilt, true_bearing, near, self.imu_var)


def iter_synced_frames(
    reader: BagReader,
    topic_map: TopicMap,
    tally: Tally,
    plan: BagPlan | None = None,
    prior_max_age_s: float = 2.0,
):
    """
    Yield a :class:`SyncedFrame` for every usable image, in receive-time order.

    Images that cannot be processed (no camera intrinsics, size not matching camera_info,
    duplicate stamp, no site) are counted on ``tally`` as skipped with a reason (see the package
    docstring).

    Parameters
    ----------
    reader : BagReader
        The open bag.
    topic_map : TopicMap
        Topics, mosaic layout, mounting, fallbacks and tolerances.
    tally : Tally
        Per-topic counts, updated.
    plan : BagPlan, optional
        The bag's plan (:func:`plan_bag`), computed when None.
    prior_max_age_s : float, default 2.0
        Largest age [s] of the IMU sample used as the ``imu`` prior.

    Yields
    ------
    SyncedFrame
        One image with its camera, site, tilt and reference bearing [deg].

    """
    sync = _FrameSync(topic_map, tally, plan or plan_bag(reader, topic_map), prior_max_age_s)
    for topic, mtype, log_ns, raw in prefetched(reader.messages(list(sync.wanted))):
        role = sync.wanted[topic]
        decoded = sync.decode(topic, role, mtype, raw)
        if decoded is None:
            continue  # skipped: nothing new, nothing released
        t, value = decoded
        if role == 'image':
            if not sync.add_image(topic, t, log_ns, value):
                continue
        else:
            sync.add_aux(topic, role, t, value)
        yield from sync.due(log_ns)
    yield from sync.rest()
