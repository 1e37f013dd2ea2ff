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
The renderer: a scene plus an attitude and a sun position in, a :class:`Frame` out.

The pipeline is built once per scene from what it declares:

1. geometry (always): the sun and zenith directions rotated into the camera frame;
2. sky polarization (always): the scene's sky model at the selected pixels' rays;
3. radiance (only if ``scene.radiance``): relative sky brightness at those rays;
3b. atmosphere (only if ``scene.atmosphere`` declares it): haze, clouds and a skyline over the
clear sky
   (:mod:`polarization_compass.atmosphere`; a declared atmosphere always gives ``intensity``);
3c. optics (only if ``scene.optics`` declares it): vignetting, the sun and its glare, lens-flare
ghosts
   (:mod:`polarization_compass.optics`);
4. sensor (only if ``scene.sensor`` declares effects): mosaic, noise, quantisation and demosaic,
giving the *measured* AoP/DoP and the raw mosaic.

Over a pixel block (full frame or stride-1 region), clouds and lens effects run in one pass with
the sky model (:mod:`polarization_compass.sky_effects`): the same formulas in the same order, the
image written to memory once instead of three times; other scenes run the stages one by one.

Stages that a scene does not declare are never constructed, so they cost nothing; each stage
that runs is counted in :mod:`polarization_compass.instrumentation` (tests use that, not timing).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from . import instrumentation as instr
from .camera_pixels import PixelSelection, select_pixels, SelectedPixels
from .conventions import (
    bearing_to_psi_deg,
    CameraAttitude,
    enu_direction,
    R_BODY_CAM_DEFAULT,
    R_enu_cam_from_attitude,
)
from .scene import Scene
from .sky_models import make_sky_model

__all__ = ['Frame', 'Renderer', 'SunDirection', 'render']


@dataclass(frozen=True)
class SunDirection:
    """Sun position used for a frame: azimuth clockwise from North, geometric altitude (deg)."""

    azimuth_deg: float
    altitude_deg: float
    apparent_altitude_deg: float | None = None


@dataclass
class Frame:
    """
    One rendered frame. Images have ``pixels.shape``; invalid pixels hold aop = dop = 0.

    Except the ground of a declared ``atmosphere.ground``: invalid, but showing its reflection.

    ``aop_rad``: eq 28 convention, [-pi/2, pi/2), float32. ``dop``: [0, 1], float32. ``valid``:
    bool. ``intensity``: relative radiance (float32) when the scene declares one. ``mosaic``: raw
    division-of-focal-plane image (uint16 / uint8) when sensor effects are declared.
    ``aop_ideal_rad`` / ``dop_ideal``: the noise-free values when sensor effects changed them.
    """

    aop_rad: np.ndarray
    dop: np.ndarray
    valid: np.ndarray
    pixels: SelectedPixels
    sun: SunDirection
    attitude: CameraAttitude
    sun_cam: np.ndarray
    zenith_cam: np.ndarray
    intensity: np.ndarray | None = None
    mosaic: np.ndarray | None = None
    aop_ideal_rad: np.ndarray | None = None
    dop_ideal: np.ndarray | None = None
    meta: dict = field(default_factory=dict)
    array_intensities: np.ndarray | None = (
        None  # (units, channels) when the scene declares a photodiode array
    )

    @property
    def x_px(self) -> np.ndarray:
        """1-based pixel columns (eq 20) of the frame's pixels, shaped like ``aop_rad``."""
        return self.pixels.x_px

    @property
    def y_px(self) -> np.ndarray:
        """1-based pixel rows (eq 20) of the frame's pixels, shaped like ``aop_rad``."""
        return self.pixels.y_px

    @property
    def rays_cam(self) -> np.ndarray:
        """(3, N) float32 unit rays, in the order of ``aop_rad.reshape(-1)``."""
        return self.pixels.rays_cam

    @property
    def psi_deg(self) -> float:
        """Return the paper's yaw psi of this frame (truth), (-180, 180]."""
        return float(bearing_to_psi_deg(self.attitude.bearing_deg, self.sun.azimuth_deg))


class Renderer:
    """
    Renders frames of one scene. Construct once; call :meth:`render` per frame.

    ``pixels`` overrides the scene's pixel selection (a consumer that needs few pixels asks for
    them).
    """

    def __init__(self, scene: Scene, pixels: PixelSelection | None = None):
        self.scene = scene
        self.selection = pixels if pixels is not None else scene.pixels
        self.pixels = select_pixels(scene.camera, self.selection)
        self.sky = make_sky_model(scene.sky)
        self._all_have_rays = bool(self.pixels.has_ray.all())
        self.radiance = None
        if scene.radiance:
            from .radiance import make_radiance_model

            self.radiance = make_radiance_model(scene.radiance)
        self.sensor = None
        if scene.effects:
            from .sensor import SensorPipeline

            self.sensor = SensorPipeline.from_config(scene.sensor, scene.camera)
            if self.selection.mode not in ('full', 'region') or self.selection.stride > 1:
                from .sensor import SensorError

                raise SensorError(
                    f'sensor effects ({", ".join(scene.effects)}) need a contiguous pixel block '
                    f'(pixels full, or a region with stride 1), got {self.selection.describe()}: '
                    'a polarization mosaic has no meaning on a strided or scattered subset'
                )
        v = scene.validity
        self._limits = (
            math.cos(math.radians(v.sun_exclusion_deg)),
            math.sin(math.radians(v.min_altitude_deg)),
            v.min_dop,
        )
        self._sun_cache = None
        self._frames = 0
        self.array = None
        if scene.photodiode_array is not None:
            from .photodiode.simulate import ArraySensor

            self.array = ArraySensor.from_config(scene.photodiode_array)
        self.atmosphere = None
        if scene.atmosphere:
            from .atmosphere import Atmosphere

            self.atmosphere = Atmosphere(scene.atmosphere, scene.seed)
        self.optics = None
        if scene.optics:
            from .optics import Optics

            self.optics = Optics(scene.optics, scene.camera)
        self.sky_effects = None
        if self.atmosphere is not None or self.optics is not None:
            # clouds and lens effects over a pixel block: one pass instead of three stages
            from .sky_effects import SkyEffects

            self.sky_effects = SkyEffects.for_renderer(self)

    # ------------------------------------------------------------------------------------------
    def sun_at(self, time_utc=None) -> SunDirection:
        """
        Return the sun for this scene: fixed, or from the ephemeris.

        Fixed if the scene says so, else from the ephemeris (batched calls, interpolated).

        Parameters
        ----------
        time_utc : datetime or str, optional
            Time (UTC; a naive datetime is taken as UTC, a string as ISO 8601); default the
            scene's ``time_utc``. Ignored when the scene fixes the sun.

        Returns
        -------
        SunDirection
            Azimuth [deg, clockwise from North] and geometric altitude [deg] of the sun; the
            apparent (refracted) altitude [deg] too when the ephemeris model gives one (None for a
            fixed sun).

        Raises
        ------
        SceneError
            When ``time_utc`` cannot be read as a time (from :func:`scene.parse_time_utc`).

        References
        ----------
        .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), eqs 2-10 (the sun's
           position; the ephemeris is chosen by the scene's ``sun_model``, see
           :mod:`polarization_compass.solar`).

        """
        s = self.scene
        if s.sun_fixed is not None:
            return SunDirection(float(s.sun_fixed[0]), float(s.sun_fixed[1]))
        from .scene import parse_time_utc

        t = parse_time_utc(time_utc) if time_utc is not None else s.time_utc
        if self._sun_cache is None:
            # one batched ephemeris call per 10 minutes of scene time, interpolated (< 2e-6 deg)
            from .solar import SunCache

            self._sun_cache = SunCache(
                s.site.latitude_deg, s.site.longitude_deg, s.site.altitude_m, model=s.sun_model
            )
        p = self._sun_cache(t)
        return SunDirection(
            float(p.azimuth_deg),
            float(p.altitude_deg),
            None if p.apparent_altitude_deg is None else float(p.apparent_altitude_deg),
        )

    def render(
        self,
        attitude: CameraAttitude | None = None,
        sun: SunDirection | None = None,
        time_utc=None,
        seed: int | None = None,
    ) -> Frame:
        """
        Render one frame.

        Defaults: the scene's attitude, and its sun at its time (or ``time_utc``). The sun is
        rotated into the camera frame with the eq 21 attitude, the scene's sky model gives the AoP
        (eq 28 convention) and DoP at each selected pixel's ray, then the declared radiance,
        atmosphere, optics, sensor and photodiode-array stages run.

        Parameters
        ----------
        attitude : CameraAttitude, optional
            Camera bearing, pitch and roll [deg] (eq 21); default the scene's attitude.
        sun : SunDirection, optional
            Sun azimuth [deg, clockwise from North] and altitude [deg]; default
            :meth:`sun_at` ``(time_utc)``.
        time_utc : datetime or str, optional
            Time (UTC) of the frame: picks the ephemeris sun when ``sun`` is not given and moves
            a declared atmosphere's clouds; default the scene's time.
        seed : int, optional
            Seed of this frame's sensor noise and photodiode readings; default the scene seed
            combined with the frame index (reproducible, independent per frame).

        Returns
        -------
        Frame
            AoP [rad, eq 28, [-pi/2, pi/2)], DoP [0, 1] and validity per selected pixel, with the
            intensity, raw mosaic and noise-free values when the scene declares those stages, and
            the metadata of the frame in ``meta``.

        Raises
        ------
        SceneError
            When ``time_utc`` cannot be read as a time.

        References
        ----------
        .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), eqs 18, 21 and 28.

        """
        att = attitude if attitude is not None else self.scene.attitude
        sun_meta = self._sun_meta(sun, time_utc)
        sun = sun if sun is not None else self.sun_at(time_utc)
        with instr.stage('geometry'):
            R = R_enu_cam_from_attitude(att.bearing_deg, att.pitch_deg, att.roll_deg)
            s_enu = enu_direction(sun.azimuth_deg, sun.altitude_deg)
            sun_cam = R.T @ s_enu
            zenith_cam = R[2, :].copy()  # R^T (0, 0, 1)
        shape = self.pixels.shape
        aop, dop, valid, intensity = self._sky_atmosphere_optics(R, sun_cam, zenith_cam, time_utc)
        if intensity is not None:
            intensity = intensity.reshape(shape)
        frame = Frame(
            aop.reshape(shape),
            dop.reshape(shape),
            valid.reshape(shape),
            self.pixels,
            sun,
            att,
            sun_cam,
            zenith_cam,
            intensity=intensity,
        )
        self._sensor_and_array(frame, sun_cam, seed)
        self._frames += 1
        frame.meta = {**self._frame_meta(frame, sun, att), **sun_meta}
        return frame

    def _sky_atmosphere_optics(self, R, sun_cam, zenith_cam, time_utc):
        """
        Run the sky, radiance, atmosphere and optics stages (or the one-pass render of them).

        Returns flat (aop, dop, valid, intensity or None) at the selected pixels.
        """
        if self.sky_effects is not None:
            aop, dop, valid, intensity = self.sky_effects.render(
                R, sun_cam, zenith_cam, self._limits, self._dt_s(time_utc), instr
            )
            self._mask_no_ray(aop, dop, valid)
            return aop, dop, valid, intensity
        aop, dop, valid, intensity = self._sky(sun_cam, zenith_cam)
        if self.atmosphere is not None:
            aop, dop, valid, intensity = self._atmosphere(
                R, sun_cam, zenith_cam, aop, dop, valid, intensity, time_utc
            )
        if self.optics is not None:
            if intensity is None:
                intensity = np.ones(aop.shape, np.float32)
            self.optics.apply(
                sun_cam,
                self.pixels.rays_cam,
                self.pixels.x_px,
                self.pixels.y_px,
                aop,
                dop,
                intensity,
                instr,
            )
        return aop, dop, valid, intensity

    def _sensor_and_array(self, frame, sun_cam, seed):
        """Run the declared sensor and photodiode-array stages on ``frame``, in place."""
        if self.sensor is not None:
            # reproducible and independent per frame: (scene seed, frame index) unless a seed is
            # given
            ss = np.random.SeedSequence(
                [self.scene.seed, self._frames] if seed is None else [int(seed)]
            )
            rng = np.random.default_rng(ss)
            with instr.stage('sensor'):
                self.sensor.apply(frame, rng)
        if self.array is not None:
            # the array is mounted like the default camera: body = R_BODY_CAM_DEFAULT @ camera
            ss = np.random.SeedSequence(
                [self.scene.seed, self._frames, 1] if seed is None else [int(seed), 1]
            )
            with instr.stage('photodiode_array'):
                frame.array_intensities = self.array.read(
                    R_BODY_CAM_DEFAULT @ sun_cam,
                    float(self.sky.params().get('dop_max', 1.0)),
                    np.random.default_rng(ss),
                )

    def _frame_meta(self, frame, sun, att) -> dict:
        """Return a frame's metadata: scene, sun, attitude and every stage's parameters."""
        return {
            'scene': self.scene.name,
            'sun_azimuth_deg': float(sun.azimuth_deg),
            'sun_altitude_deg': float(sun.altitude_deg),
            'sun_apparent_altitude_deg': sun.apparent_altitude_deg,
            'bearing_deg': att.bearing_deg,
            'pitch_deg': att.pitch_deg,
            'roll_deg': att.roll_deg,
            'psi_deg': frame.psi_deg,
            'sky': self.sky.params(),
            'radiance': None if self.radiance is None else self.radiance.params(),
            'effects': list(self.scene.effects),
            'sensor': None if self.sensor is None else self.sensor.params(),
            'pixels': self.selection.describe(),
            'photodiode_array': None if self.array is None else self.array.params(),
            'atmosphere': None if self.atmosphere is None else self.atmosphere.params(),
            'optics': None if self.optics is None else self.optics.params(),
            'camera': {
                'model': self.scene.camera.model,
                'width_px': self.scene.camera.width_px,
                'height_px': self.scene.camera.height_px,
                'focal_length_mm': self.scene.camera.focal_length_mm,
                'pixel_pitch_x_um': self.scene.camera.pixel_pitch_x_um,
                'pixel_pitch_y_um': self.scene.camera.pixel_pitch_y_um,
            },
        }

    def _sky(self, sun_cam, zenith_cam):
        """
        Run the sky and radiance stages at the selected pixels.

        Returns them flat: (aop, dop, valid, intensity or None).
        """
        with instr.stage('sky.' + self.sky.name):
            aop, dop, valid = self.sky.polarization(
                sun_cam, zenith_cam, self.pixels.rays_cam, self._limits
            )
        self._mask_no_ray(aop, dop, valid)
        intensity = None
        if self.radiance is not None:
            with instr.stage('radiance.' + self.radiance.name):
                intensity = self.radiance.radiance(sun_cam, zenith_cam, self.pixels.rays_cam)
        return aop, dop, valid, intensity

    def _mask_no_ray(self, aop, dop, valid):
        """Mark fisheye pixels beyond the lens' field as no sky (invalid, 0/0), in place."""
        if not self._all_have_rays:
            no_ray = ~self.pixels.has_ray.reshape(-1)
            valid[no_ray] = False
            aop[no_ray] = 0.0
            dop[no_ray] = 0.0

    def _dt_s(self, time_utc) -> float:
        """Return the time since the scene's ``time_utc`` [s] (0 without a time)."""
        if time_utc is None:
            return 0.0
        from .scene import parse_time_utc

        return (parse_time_utc(time_utc) - self.scene.time_utc).total_seconds()

    def _atmosphere(self, R, sun_cam, zenith_cam, aop, dop, valid, intensity, time_utc):
        """
        Apply the declared atmosphere over the clear sky (flat arrays).

        The clouds move with the time since the scene's ``time_utc``. Without a radiance model the
        base radiance is the haze's Preetham sky if haze is declared, else uniform 1.
        """
        if intensity is None:
            if self.atmosphere.haze is not None:
                with instr.stage('radiance.preetham'):
                    intensity = self.atmosphere.haze.radiance_model.radiance(
                        sun_cam, zenith_cam, self.pixels.rays_cam
                    )
            else:
                intensity = np.ones(aop.shape, np.float32)
        dt_s = self._dt_s(time_utc)
        sel = self.selection
        block = (
            self.pixels.shape
            if (sel.mode in ('full', 'region') and sel.stride == 1 and len(self.pixels.shape) == 2)
            else None
        )
        ground = {}
        if self.atmosphere.ground is not None:
            ground = {
                'sky_at': self._clear_sky_at(sun_cam, zenith_cam),
                'has_ray': None if self._all_have_rays else self.pixels.has_ray.reshape(-1),
            }
        return self.atmosphere.apply(
            R,
            self.pixels.rays_cam,
            aop,
            dop,
            valid,
            intensity,
            self._limits[2],
            dt_s,
            instr,
            block,
            **ground,
        )

    def _clear_sky_at(self, sun_cam, zenith_cam):
        """
        Return ``sky_at(rays) -> (aop, dop, radiance)``: the clear sky along any camera-frame rays.

        No validity limits; the radiance as :meth:`_atmosphere` starts from it (the radiance
        model, else haze's Preetham sky, else 1). What a declared ground reflects.
        """

        def sky_at(rays):
            aop, dop, _ = self.sky.polarization(sun_cam, zenith_cam, rays)
            if self.radiance is not None:
                inten = self.radiance.radiance(sun_cam, zenith_cam, rays)
            elif self.atmosphere.haze is not None:
                inten = self.atmosphere.haze.radiance_model.radiance(sun_cam, zenith_cam, rays)
            else:
                inten = np.ones(aop.shape, np.float32)
            return aop, dop, np.array(inten, dtype=np.float32)

        return sky_at

    def render_sky(self, sun_cam, zenith_cam):
        """
        Render a scene without sensor effects at the selected pixels, and nothing else.

        Flat (N,) aop, dop, valid and intensity (None without a radiance model) in the selection's
        pixel order, for the sun and the zenith already in the camera frame (``R.T @ s_enu`` and
        ``R[2]`` for the camera-to-ENU rotation ``R = conventions.R_enu_cam_from_attitude(...)``,
        as :meth:`render` computes them). No Frame, no metadata, no geometry stage: for error-map
        sweeps, which render 1e5 frames and compute the rotations of a whole chunk at once. A scene
        with sensor effects is refused (its frames need :meth:`render`).

        Parameters
        ----------
        sun_cam : numpy.ndarray
            (3,) unit vector to the sun in the camera optical frame.
        zenith_cam : numpy.ndarray
            (3,) unit vector to the zenith (ENU Up) in the camera optical frame.

        Returns
        -------
        aop : numpy.ndarray
            (N,) float32 AoP [rad] in the eq 28 convention, [-pi/2, pi/2); 0 where invalid.
        dop : numpy.ndarray
            (N,) float32 DoP in [0, 1]; 0 where invalid.
        valid : numpy.ndarray
            (N,) bool: the pixel sees sky outside the scene's validity limits (sun exclusion,
            minimum altitude and DoP).
        intensity : numpy.ndarray or None
            (N,) float32 relative radiance, None without a radiance model.

        Raises
        ------
        SensorError
            When the scene declares sensor effects.
        OpticsError
            When the scene declares lens optics.
        AtmosphereError
            When the scene declares an atmosphere.

        References
        ----------
        .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), eqs 18 and 28.

        """
        if self.sensor is not None:
            from .sensor import SensorError

            raise SensorError('render_sky: the scene declares sensor effects; use render()')
        if self.optics is not None:
            from .optics import OpticsError

            raise OpticsError(
                'render_sky: the scene declares lens optics (sun glare, flare, vignetting); use '
                'render()'
            )
        if self.atmosphere is not None:
            from .atmosphere import AtmosphereError

            raise AtmosphereError(
                'render_sky: the scene declares an atmosphere (clouds/haze/skyline need the '
                'full camera attitude); use render()'
            )
        return self._sky(sun_cam, zenith_cam)

    def _sun_meta(self, sun: SunDirection | None, time_utc) -> dict:
        """
        How this frame's sun was obtained, and the time only when the sun is that time's.

        ``sun_source``: ``ephemeris`` (computed for ``time_utc`` with ``sun_model``), ``scene``
        (the scene fixes the sun) or ``given`` (the caller passed it, e.g. ``render
        --sun-altitude/--sun-azimuth``). ``sun_fixed`` is true unless the ephemeris was used. A
        fixed sun has ``time_utc`` None: no time was used (a caller that passes both a sun and a
        time gets its time recorded as given).
        """
        from .scene import parse_time_utc

        t = None if time_utc is None else parse_time_utc(time_utc)
        if sun is not None:
            src, model = 'given', None
        elif self.scene.sun_fixed is not None:
            src, model, t = 'scene', None, None
        else:
            src, model = 'ephemeris', self.scene.sun_model
            t = self.scene.time_utc if t is None else t
        iso = None if t is None else t.isoformat().replace('+00:00', 'Z')
        return {
            'sun_source': src,
            'sun_fixed': src != 'ephemeris',
            'sun_model': model,
            'time_utc': iso,
        }


def render(scene: Scene | None = None, **kwargs) -> Frame:
    """
    Render one frame of a scene in a single call.

    One-shot convenience: ``render(scene, attitude=..., sun=...)``.

    Parameters
    ----------
    scene : Scene, optional
        The scene; default :func:`scene_load.default_scene`.
    **kwargs
        ``attitude``, ``sun``, ``time_utc`` and ``seed``, passed to :meth:`Renderer.render`.

    Returns
    -------
    Frame
        The rendered frame (see :meth:`Renderer.render`).

    Raises
    ------
    SceneError
        When ``time_utc`` cannot be read as a time.
    SensorError
        When the scene's sensor effects need a contiguous pixel block it does not select.

    """
    from .scene_load import default_scene

    return Renderer(scene or default_scene()).render(**kwargs)
