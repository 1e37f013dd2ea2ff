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
Offline replay of a recorded field run (rosbag2), faster than real time.

Every method's heading, raw and tilt-corrected, against the reference heading. ROS-free (reads bags
with `rosbags`).

Same code as the nodes
----------------------
Per image, in the order the ``heading_estimator`` node does it: the camera from camera_info
(:func:`~polarization_compass.bag.decode_camera_info`), the sun at the image stamp for the site of
the latest NavSatFix (:class:`~polarization_compass.pipeline.SunSource`), the IMU attitude
interpolated to the stamp (:class:`~polarization_compass.pipeline.AttitudeBuffer`, same tolerance),
the tilt given to ``tilt_aware`` only and the 180 deg prior from the IMU's yaw (or the last
heading), both decided by the node's :class:`~polarization_compass.pipeline.TiltAndPrior`, and
:class:`~polarization_compass.pipeline.HeadingFrontEnd` (demosaic -> observation -> estimator). The
tilt correction is the ``tilt_corrector``'s
(:meth:`~polarization_compass.correction.TiltCorrector.correct_bearing`), and errors and statistics
are the ``error_evaluator``'s (:class:`~polarization_compass.evaluation.StampMatcher`, truth = the
reference interpolated to the image stamp). Headings only known modulo 180 deg are not evaluated,
as the nodes do not publish them. Methods that demosaic alike share one observation per frame (the
front end's own ``observation``).

Reading
-------
One pass over the bag in receive-time order. Auxiliary streams (IMU, reference, NavSatFix,
camera_info) are buffered by header stamp; an image is processed once the reader is ``lookahead_s``
of receive time past it (or at the end of the bag), so data stamped shortly after an image (and
messages that arrive out of order) are used. Memory is bounded by the images inside the look-ahead.
Every message read is accounted for (:class:`~polarization_compass.bag.Tally`): used, or skipped
with a reason; out-of-order stamps and images without IMU/reference data near their stamp are
noted.

Modules
-------
:mod:`.sync` (bag plan, synchronised frames), :mod:`.processing` (the nodes' per-frame chain, rows,
correction), :mod:`.threads` (method groups over one read of the bag, :func:`replay_bag`),
:mod:`.outputs` (CSV, JSON, figures).

"""

from __future__ import annotations

from .outputs import plot_replay, write_outputs
from .processing import default_error_map, FramePipeline, MethodRow, ReplayConfig, ReplayError
from .sync import BagPlan, iter_synced_frames, plan_bag, prefetched, SyncedFrame
from .threads import default_workers, method_groups, replay_bag, ReplayResult

__all__ = [
    'SyncedFrame',
    'BagPlan',
    'plan_bag',
    'iter_synced_frames',
    'ReplayConfig',
    'FramePipeline',
    'MethodRow',
    'ReplayResult',
    'replay_bag',
    'write_outputs',
    'ReplayError',
    'method_groups',
    'default_workers',
    'plot_replay',
    'prefetched',
    'default_error_map',
]
