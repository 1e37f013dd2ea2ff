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
The diagnostic figure of every N-th frame of a replayed bag (``replay --plots-every N``).

After :func:`polarization_compass.replay.replay_bag`, the bag is read once more; every N-th
synchronised image (counting from the first) is drawn with what each method answered on it (the
replay's rows at that stamp) by :func:`polarization_compass.sky_view.view_from_mosaic` and the
fast renderer (:func:`polarization_compass.diagnostic_rgb.quick_rgb`: the figure's layers in tens
of ms, where matplotlib takes ~1 s), as ``frame_<index>_<stamp>.png``.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ['results_of_rows', 'write_frame_figures']


def results_of_rows(rows) -> list:
    """
    Turn the replay's rows of one frame back into heading results (for the figure).

    Parameters
    ----------
    rows : list of MethodRow
        One frame's rows.

    Returns
    -------
    list of HeadingResult
        psi = raw bearing - sun azimuth, the status, reason, sigma and pixels of each row.

    """
    from .conventions import bearing_to_yaw_enu_deg, wrap_180_deg_float
    from .estimators import HeadingResult, Status

    out = []
    for r in rows:
        b = r.raw_bearing_deg
        out.append(
            HeadingResult(
                r.method,
                Status(r.status),
                r.reason,
                psi_deg=None if b is None else wrap_180_deg_float(b - r.sun_azimuth_deg),
                bearing_deg=b,
                yaw_enu_deg=None if b is None else float(bearing_to_yaw_enu_deg(b)),
                sigma_deg=r.sigma_deg,
                pixels=r.pixels,
                axial=r.status == Status.AMBIGUOUS.value,
            )
        )
    return out


def write_frame_figures(bag_path, result, topic_map, config, every: int, out_dir) -> list:
    """
    Write the diagnostic figure of every ``every``-th frame of a replayed bag.

    Parameters
    ----------
    bag_path : str
        The bag that was replayed.
    result : ReplayResult
        The replay's result (its rows).
    topic_map : TopicMap
        The topics and mosaic layout it was replayed with.
    config : ReplayConfig
        The replay's settings (demosaic).
    every : int
        Draw frames 0, every, 2 every, ...
    out_dir : str or Path
        Output directory (``frames/`` is made in it).

    Returns
    -------
    list of pathlib.Path
        The figures written.

    """
    import cv2

    from .bag.reader import BagReader, Tally
    from .diagnostic_rgb import quick_rgb
    from .mosaic import layout_from_mapping
    from .pipeline.rules import SensorReadout
    from .pipeline.sun import Sun
    from .replay.sync import iter_synced_frames
    from .sky_view import view_from_mosaic

    by_stamp: dict = {}
    for row in result.rows:
        by_stamp.setdefault(row.stamp_ns, []).append(row)
    layout = layout_from_mapping(topic_map.mosaic)
    readout = SensorReadout(topic_map.readout_flip)  # the image as the replay read it
    folder = Path(out_dir) / 'frames'
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    with BagReader(bag_path) as reader:
        for k, frame in enumerate(iter_synced_frames(reader, topic_map, Tally())):
            rows = by_stamp.get(frame.stamp_ns)
            if k % every or not rows:
                continue
            r0 = rows[0]
            view = view_from_mosaic(
                readout.image(frame.mosaic),
                readout.camera(frame.camera),
                Sun(r0.sun_azimuth_deg, r0.sun_altitude_deg, 'replay'),
                results_of_rows(rows),
                layout.angles_deg,
                layout.pol45_toward,
                config.demosaic,
                r0.pitch_deg,
                r0.roll_deg,
                max_side_px=256,
                sampled=True,
                label=f'{Path(bag_path).name} frame {k}, stamp {frame.stamp_ns / 1e9:.3f} s',
            )
            path = folder / f'frame_{k:05d}_{frame.stamp_ns}.png'
            if not cv2.imwrite(str(path), quick_rgb(view, 800)[..., ::-1]):
                raise OSError(f'cannot write {path}')
            written.append(path)
    return written
