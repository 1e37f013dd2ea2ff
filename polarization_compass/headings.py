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
The file entry of the one road: frame file, Stokes planes or raw mosaic -> headings.

``polarization-compass estimate``, the bench and the tests turn an input file into headings here;
the nodes and the replay feed live mosaics to
:class:`polarization_compass.pipeline.HeadingFrontEnd`. Both take the same steps, each written
once in :mod:`polarization_compass.pipeline`:

1. :func:`estimate_file` reads the input
   (:func:`polarization_compass.real_input.load_polarization_input`): a frame file written by
   ``render`` goes to :func:`frame_headings`, a real image (raw mosaic or Stokes planes, with a
   camera file) to :func:`real_headings`.
2. Where the sun was: :func:`polarization_compass.pipeline.sun.resolve_sun` (given, from the
   frame's meta, or from the ephemeris); the camera's pitch and roll: :func:`camera_tilt`.
3. One estimator per method with the knobs each method declares
   (:func:`polarization_compass.pipeline.methods.make_estimators`; ``knob_specs``: names and
   ranges are checked there, nowhere else).
4. The observation: a frame's raw mosaic demosaiced for each method's pixels by
   :func:`polarization_compass.pipeline.front_end.mosaic_observation` (the front end's own step),
   or its stored AoP/DoP; a real image's whole sky by
   :func:`polarization_compass.pipeline.real_image.real_observation`.
5. The estimate, checked against the whole sky on real images
   (:func:`polarization_compass.pipeline.front_end.estimate_checked` on
   :func:`polarization_compass.pipeline.sampling.observation_sky_sample`, as the front end does on
   :func:`~polarization_compass.pipeline.sampling.whole_sky_sample`), its sigma grown by the
   camera file's principal point uncertainty (a frame file's rendered camera is exact),
   ``inconsistent`` across methods, then the polarizer gate
   (:func:`polarization_compass.polarizer_check.check_frame` and
   :func:`~polarization_compass.polarizer_check.gate_result`, as the node's
   :class:`~polarization_compass.pipeline.monitors.PolarizerMonitor`).
6. Each result as a JSON-ready dict (:func:`polarization_compass.pipeline.methods.result_row`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
import time

from .errors import CompassError
from .pipeline.front_end import estimate_checked, mosaic_observation, MosaicReading
from .pipeline.methods import make_estimators, REAL_SKY_KNOBS, result_row
from .pipeline.real_image import real_observation
from .pipeline.sampling import observation_sky_sample
from .pipeline.sun import resolve_sun, Sun

__all__ = [
    'EstimateOptions',
    'camera_tilt',
    'estimate_file',
    'frame_headings',
    'real_headings',
]


@dataclass
class EstimateOptions:
    """
    Everything :func:`estimate_file` needs besides the input path (``estimate``'s options).

    ``methods`` names registered methods; ``knobs`` apply to every selected method that declares
    them; ``stride`` overrides each method's default. ``camera_yaml``, ``mask_path``, ``bits`` and
    ``demosaic`` concern real images; ``use_stored`` frame files. The sun: ``sun_azimuth_deg`` and
    ``sun_altitude_deg`` if given, else a frame's meta, else the ephemeris for ``lat_deg``,
    ``lon_deg`` and ``time_utc`` (ISO 8601). ``ifov_k`` None is the IFOV check's default.
    """

    methods: list = field(default_factory=list)
    knobs: dict = field(default_factory=dict)
    stride: int | None = None
    camera_yaml: str | None = None
    mask_path: str | None = None
    bits: int | None = None
    demosaic: str = 'superpixel'
    ifov_k: float | None = None
    sun_azimuth_deg: float | None = None
    sun_altitude_deg: float | None = None
    lat_deg: float | None = None
    lon_deg: float | None = None
    time_utc: str | None = None
    pitch_deg: float | None = None
    roll_deg: float | None = None
    prior_bearing_deg: float | None = None
    sky_check: bool = True
    use_stored: bool = False


def estimate_file(path, options: EstimateOptions, seen: dict | None = None) -> list[dict]:
    """
    Turn an input file into one result dict per method: THE road from a file to headings.

    Parameters
    ----------
    path : str or Path
        A frame file written by ``render`` (.npz) or a real image: raw mosaic (.png/.tif/.npy) or
        Stokes planes (.npz with s0, s1, s2, or a 3-page .tif).
    options : EstimateOptions
        Methods, knobs, the sun, the tilt and the input's settings.
    seen : dict, optional
        Filled, when given, with what the estimators saw (for the diagnostic figure,
        :mod:`polarization_compass.sky_view`): ``kind`` ('frame' or the real input's kind),
        ``sun``, ``results`` (the :class:`HeadingResult` of each method), ``observations``
        (method name to its observation), and ``frame`` and ``plan`` (a frame file; ``plan``
        the :class:`~polarization_compass.pipeline.front_end.MosaicReading` of its mosaic, None
        for stored AoP/DoP) or ``input``, ``camera_file``, ``mask`` and ``data_mask`` (a real
        image).

    Returns
    -------
    list of dict
        One JSON-ready dict per method
        (:func:`~polarization_compass.pipeline.methods.result_row`), in the order of
        ``options.methods``.

    Raises
    ------
    CompassError
        A frame file with ``camera_yaml`` or ``mask_path``; a real image without ``camera_yaml``
        or with ``use_stored``; and every user error of the steps (bad file, knob, sun).

    """
    from .real_input import load_polarization_input

    inp = load_polarization_input(path, options.bits)
    if inp.kind == 'frame':
        if options.mask_path or options.camera_yaml:
            raise CompassError(
                '--camera and --mask apply to real images; a frame file carries its camera'
            )
        from .frame_io import load_frame_npz

        frame = load_frame_npz(path)
        return frame_headings(frame, options, _options_sun(frame.meta, options), seen)
    if not options.camera_yaml:
        raise CompassError(
            f'{path}: a real image needs --camera CAMERA.yaml (ROS camera_calibration format)'
        )
    if options.use_stored:
        raise CompassError('--use-stored applies to frame files')
    from .camera_file import load_camera_yaml
    from .real_input import load_mask

    cam_file = load_camera_yaml(options.camera_yaml)
    sun = _options_sun({}, options)
    mask = None
    if options.mask_path:
        shape = inp.stokes[0].shape if inp.kind == 'stokes' else inp.mosaic.shape
        mask = load_mask(options.mask_path, shape, cam_file.camera.shape)
    if cam_file.readout_flip:  # the camera model is the sensor's: read the image as it sees it
        inp, mask = _unflipped(inp, mask, cam_file.readout_flip)
    return real_headings(inp, cam_file, options, sun, mask, seen)


def _unflipped(inp, mask, readout_flip: str):
    """Return the input and mask with a mirrored readout undone (:func:`camera.unflip`)."""
    import dataclasses

    import numpy as np

    from .camera_file import unflip

    def un(a):
        return np.ascontiguousarray(unflip(a, readout_flip))

    if inp.kind == 'mosaic':
        inp = dataclasses.replace(inp, mosaic=un(inp.mosaic))
    else:
        inp = dataclasses.replace(inp, stokes=tuple(un(a) for a in inp.stokes))
    return inp, None if mask is None else un(mask)


def _options_sun(meta: dict, options: EstimateOptions) -> Sun:
    return resolve_sun(
        meta,
        options.sun_azimuth_deg,
        options.sun_altitude_deg,
        options.lat_deg,
        options.lon_deg,
        options.time_utc,
    )


def camera_tilt(options: EstimateOptions, camera_file=None) -> tuple:
    """
    Resolve the camera pitch and roll [deg] the estimators use for an input file.

    The one place where the body attitude given for a frame becomes the camera's: the
    observation, the whole-sky check and the polarizer check all read what this returns. A real
    image's camera file composes its ``mount:`` with the given body ``pitch_deg``/``roll_deg``
    (:func:`polarization_compass.mount.camera_tilt_deg`, issue 28); a frame file's tilt is its
    rendered camera's, as given.

    Parameters
    ----------
    options : EstimateOptions
        ``pitch_deg`` and ``roll_deg`` as given (None: unknown).
    camera_file : CameraFile, optional
        The real image's camera file; None for a frame file (its camera is the rendered one).

    Returns
    -------
    tuple
        (pitch_deg, roll_deg) of the camera [deg, eq 21]; None when unknown.

    """
    if camera_file is None:
        return options.pitch_deg, options.roll_deg
    from .mount import camera_tilt_deg  # the body's --pitch/--roll composed with the mount

    return camera_tilt_deg(options.pitch_deg, options.roll_deg, camera_file.mount)


# --------------------------------------------------------------------------------------------
# Frame files (written by ``render``)
# --------------------------------------------------------------------------------------------
def frame_headings(
    frame, options: EstimateOptions, sun: Sun, seen: dict | None = None
) -> list[dict]:
    """
    Estimate the heading of a frame file with every selected method.

    The raw mosaic, when the frame holds one and ``options.use_stored`` is off, is demosaiced for
    each method's own pixels (the scene's demosaic and layout from the frame's meta, else
    superpixel and the IMX250MZR layout, recorded as ``assumed``); otherwise the stored AoP/DoP
    make one observation shared by all methods. A frame whose meta has ``psi_deg`` gets the error.

    Parameters
    ----------
    frame : FrameFile
        The frame (:func:`polarization_compass.frame_io.load_frame_npz`).
    options : EstimateOptions
        Methods, knobs, stride, tilt, prior, ``use_stored`` and ``ifov_k``.
    sun : Sun
        Where the sun was (:func:`~polarization_compass.pipeline.sun.resolve_sun`).
    seen : dict, optional
        Filled with what the estimators saw (:func:`estimate_file`).

    Returns
    -------
    list of dict
        One dict per method (:func:`~polarization_compass.pipeline.methods.result_row`).

    Raises
    ------
    CompassError
        A bad knob or stride; the mosaic does not match the AoP image.

    """
    estimators = make_estimators(options.methods, options.knobs, options.stride)
    pitch, roll = camera_tilt(options)
    source = {'sun': sun.source}
    plan = None
    if frame.mosaic is not None and not options.use_stored:
        plan, source['input'] = _mosaic_plan(frame, options.ifov_k)
    else:
        source['input'] = 'stored AoP/DoP' + (
            ' (--use-stored)' if frame.mosaic is not None else ''
        )
    truth = frame.meta.get('psi_deg')
    if not (isinstance(truth, (int, float)) and math.isfinite(truth)):
        truth = None
    out, stored_obs = [], None
    for _name, est, kn in estimators:
        t0 = time.perf_counter()
        if plan is not None:
            obs = mosaic_observation(
                frame.mosaic,
                frame.camera,
                sun.azimuth_deg,
                sun.altitude_deg,
                plan,
                est.pixels_needed(frame.camera),
                pitch,
                roll,
                options.prior_bearing_deg,
            )
        else:
            if stored_obs is None:
                stored_obs = _stored_observation(
                    frame, sun, pitch, roll, options.prior_bearing_deg
                )
            obs = stored_obs
        res = estimate_checked(est, obs, principal_point_sigma_px=0.0)  # the rendered camera
        dt = (time.perf_counter() - t0) * 1e3
        out.append(result_row(res, dt, kn, source, None if truth is None else float(truth)))
        if seen is not None:
            seen.setdefault('results', []).append(res)
            seen.setdefault('observations', {})[_name] = obs
    if seen is not None:
        seen.update(kind='frame', sun=sun, frame=frame, plan=plan)
    return out


def _mosaic_plan(frame, ifov_k: float | None) -> tuple:
    """
    Read from a frame's meta how to read its mosaic; CompassError if it cannot be.

    Returns the :class:`~polarization_compass.pipeline.front_end.MosaicReading` (IFOV check
    ``ifov_k``, None its default) and what the output says of it (``source['input']``).
    """
    from .demosaic import IFOV_K_DEFAULT
    from .mosaic import IMX250MZR_LAYOUT, IMX250MZR_POL45

    _sensor, mos, method, bits, full_well = _sensor_meta(frame.meta)
    layout, pol45 = mos.get('layout'), mos.get('pol45_toward')
    assumed = []
    if layout is None:
        layout = [list(r) for r in IMX250MZR_LAYOUT]
        assumed.append('layout')
    if pol45 is None:
        pol45 = IMX250MZR_POL45
        assumed.append('pol45_toward')
    shp, mshp = frame.aop_rad.shape, frame.mosaic.shape
    if method is None:
        method = 'bilinear' if mshp == shp else 'superpixel'
        assumed.append('demosaic')
    if method == 'bilinear' and mshp == shp:
        origin = (frame.x_px.flat[0], frame.y_px.flat[0])
    elif method == 'superpixel' and len(shp) == 2 and mshp == (2 * shp[0], 2 * shp[1]):
        origin = (frame.x_px.flat[0] - 0.5, frame.y_px.flat[0] - 0.5)
    else:
        raise CompassError(
            f"the frame's mosaic {mshp} does not match its {shp} AoP image for a {method} "
            'demosaic; use --use-stored'
        )
    sat = float((1 << bits) - 1) if bits else full_well
    source = {
        'mosaic': list(mshp),
        'demosaic': method,
        'layout': layout,
        'pol45_toward': pol45,
        'assumed': assumed,
        'saturation_level': sat,
    }
    origin = (int(round(origin[0])), int(round(origin[1])))
    reading = MosaicReading(
        layout,
        pol45,
        method,
        origin,
        sat,
        IFOV_K_DEFAULT if ifov_k is None else ifov_k,
        frame.intensity is not None,
    )
    return reading, source


def _stored_observation(frame, sun: Sun, pitch, roll, prior):
    """Build the observation of the frame's stored AoP/DoP (every method reads the same one)."""
    from .estimators import Observation

    return Observation(
        frame.aop_rad,
        frame.dop,
        frame.valid,
        frame.rays_cam(),
        frame.x_px,
        frame.y_px,
        frame.camera,
        sun.azimuth_deg,
        sun.altitude_deg,
        frame.intensity,
        pitch,
        roll,
        prior,
    )


def _sensor_meta(meta: dict):
    """
    Read the sensor settings from a frame's meta, types checked.

    Returns (sensor, mosaic, demosaic, quantization_bits, full_well_e). A frame file is user input,
    so a wrong type is a :class:`FrameFileError` (one line, exit 2), not a crash.
    """
    from .frame_io import FrameFileError

    def section(d, key):
        v = d.get(key)
        if v is None:
            return {}
        if not isinstance(v, dict):
            raise FrameFileError(f'frame meta: {key} must be a mapping, got {type(v).__name__}')
        return v

    sensor = section(meta, 'sensor')
    mos = section(sensor, 'mosaic')
    method = sensor.get('demosaic')
    if method is not None and method not in ('superpixel', 'bilinear'):
        raise FrameFileError(
            f'frame meta: sensor.demosaic must be superpixel or bilinear, got {method!r}'
        )
    bits = sensor.get('quantization_bits')
    if bits is not None and (
        isinstance(bits, bool) or not isinstance(bits, int) or not 1 <= bits <= 32
    ):
        raise FrameFileError(
            f'frame meta: sensor.quantization_bits must be an integer in [1, 32], got {bits!r}'
        )
    full_well = section(sensor, 'exposure').get('full_well_e')
    if full_well is not None and (
        isinstance(full_well, bool)
        or not isinstance(full_well, (int, float))
        or not math.isfinite(full_well)
        or full_well <= 0
    ):
        raise FrameFileError(
            f'frame meta: sensor.exposure.full_well_e must be a positive number, got {full_well!r}'
        )
    return sensor, mos, method, bits, None if full_well is None else float(full_well)


# --------------------------------------------------------------------------------------------
# Real images (raw mosaic or Stokes planes, with a camera file)
# --------------------------------------------------------------------------------------------
def real_headings(
    inp, cam_file, options: EstimateOptions, sun: Sun, mask=None, seen: dict | None = None
) -> list[dict]:
    """
    Estimate the heading of a real image with every selected method, checked against the sky.

    The methods with the robust refit get
    :data:`~polarization_compass.pipeline.methods.REAL_SKY_KNOBS` unless the user set
    ``outlier_deg``. With ``options.sky_check`` every result is checked against the whole sky
    (:func:`polarization_compass.skyfit_assess.assess_result`: misfit sigma, 180 deg side,
    ``poor_fit``) and, with several methods, against each other (``inconsistent``).

    Parameters
    ----------
    inp : PolarizationInput
        The image (:func:`polarization_compass.real_input.load_polarization_input`).
    cam_file : CameraFile
        The camera and its polarizer (:func:`polarization_compass.camera_file.load_camera_yaml`).
    options : EstimateOptions
        Methods, knobs, stride, demosaic, IFOV check, tilt, prior and ``sky_check``.
    sun : Sun
        Where the sun was.
    mask : numpy.ndarray of bool, optional
        True = sky (:func:`polarization_compass.real_input.load_mask`).
    seen : dict, optional
        Filled with what the estimators saw (:func:`estimate_file`).

    Returns
    -------
    list of dict
        One dict per method (:func:`~polarization_compass.pipeline.methods.result_row`).

    """
    from .skyfit_assess import mark_inconsistent

    estimators = make_estimators(options.methods, options.knobs, options.stride, REAL_SKY_KNOBS)
    pitch, roll = camera_tilt(options, cam_file)
    obs, keep = real_observation(
        inp,
        cam_file,
        sun.azimuth_deg,
        sun.altitude_deg,
        mask,
        options.demosaic,
        pitch,
        roll,
        options.prior_bearing_deg,
        options.ifov_k,
    )
    check = options.sky_check
    sample = observation_sky_sample(obs) if check else None
    source = {
        'sun': sun.source,
        'input': {
            'kind': inp.kind,
            'path': inp.path,
            'layout': [list(r) for r in cam_file.layout],
            'pol45_toward': cam_file.pol45_toward,
            'assumed': [] if cam_file.layout_given else ['layout', 'pol45_toward'],
            'usable_pixels': int(obs.valid.sum()),
        },
    }
    results, times = [], []
    for _name, est, _kn in estimators:
        t0 = time.perf_counter()
        res = estimate_checked(est, obs, check, sample, cam_file.principal_point_sigma_px)
        times.append((time.perf_counter() - t0) * 1e3)
        results.append(res)
    if check and len(results) > 1:
        results = mark_inconsistent(results)
    results = _polarizer_gated(results, inp, cam_file, sun, (pitch, roll), keep, source)
    if seen is not None:
        seen.update(kind=inp.kind, sun=sun, results=list(results), input=inp, mask=mask)
        seen.update(camera_file=cam_file, data_mask=keep)
        seen['observations'] = {name: obs for name, _, _ in estimators}
    return [result_row(r, dt, kn, source) for r, dt, (_, _, kn) in zip(results, times, estimators)]


def _polarizer_gated(results, inp, cam_file, sun: Sun, tilt: tuple, keep, source: dict) -> list:
    """
    Check the frame against the polarizer hypotheses; a contradicted convention is never ``ok``.

    :func:`polarization_compass.polarizer_check.check_frame` at the known sun altitude and tilt,
    on the pixels the methods may use (``keep``); its verdict goes into ``source`` and a
    ``contradicted`` one turns every heading into ``poor_fit`` naming the fix
    (:func:`~polarization_compass.polarizer_check.gate_result`).
    """
    from .polarizer_check import check_frame, gate_result

    t0 = time.perf_counter()
    data = inp.stokes if inp.kind == 'stokes' else inp.mosaic
    sat = inp.saturation_level if inp.kind == 'mosaic' else None
    rep = check_frame(
        inp.kind,
        data,
        sat,
        cam_file.camera,
        cam_file.layout,
        cam_file.pol45_toward,
        sun.altitude_deg,
        *tilt,
        keep,
    )
    source['polarizer_check'] = {
        'verdict': rep['verdict'],
        'margin': rep['margin'],
        'best': rep['best'],
        'ms': round((time.perf_counter() - t0) * 1e3, 1),
    }
    return [gate_result(r, rep) for r in results]
