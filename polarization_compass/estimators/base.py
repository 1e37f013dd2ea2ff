"""The shared estimator interface: what goes in (:class:`Observation`), what comes out
(:class:`HeadingResult`), and the registry (:func:`make_estimator`).

Angles follow :mod:`polarization_compass.conventions`. A result never carries NaN or inf: a value
that does not exist is ``None`` and ``status``/``reason`` say why.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from enum import Enum
from typing import Callable

import numpy as np

from ..camera import CameraModel, PixelSelection
from ..conventions import psi_to_bearing_deg
from ..errors import CompassError

__all__ = ["Status", "HeadingResult", "Observation", "Estimator", "make_estimator", "register_estimator",
           "estimator_names", "EstimatorError"]


class EstimatorError(CompassError):
    """Unknown method or out-of-range knob."""


class Status(str, Enum):
    OK = "ok"
    AMBIGUOUS = "ambiguous"                  # solar meridian found, 180 deg ambiguity not resolved
    SUN_NEAR_ZENITH = "sun_near_zenith"      # the meridian is undefined / ill-conditioned
    SUN_BELOW_HORIZON = "sun_below_horizon"
    TOO_FEW_PIXELS = "too_few_pixels"
    OUT_OF_DOMAIN = "out_of_domain"          # e.g. tilt outside an error map
    BAD_INPUT = "bad_input"
    DEGENERATE = "degenerate"                # numerically degenerate data (e.g. all E-vectors parallel)
    INSUFFICIENT_COVERAGE = "insufficient_coverage"  # too little of the sky usable for the method's geometry


def _wrap_180(x: float) -> float:
    """:func:`~polarization_compass.conventions.wrap_180_deg` of one finite float, without numpy (the same
    floor modulo, so the same bits; ``from_psi`` runs once per estimate and sweeps make 1e5 of them)."""
    w = (x + 180.0) % 360.0 - 180.0
    return 180.0 if w == -180.0 else w


def _wrap_360(x: float) -> float:
    """:func:`~polarization_compass.conventions.wrap_360_deg` of one finite float, without numpy."""
    w = x % 360.0
    return 0.0 if w >= 360.0 else w


@dataclass(frozen=True)
class HeadingResult:
    """One heading estimate.

    ``psi_deg``: the paper's yaw (bearing of camera +y minus sun azimuth), (-180, 180].
    ``bearing_deg``: true-North bearing of the camera +y axis, [0, 360).
    ``yaw_enu_deg``: REP-103 yaw (90 - bearing), (-180, 180].
    ``sigma_deg``: calibrated 1-sigma uncertainty of the yaw (None when the caller asked for no
    uncertainty: ``estimate(obs, sigma=False)``).
    ``axial``: True when the value is only known modulo 180 deg (status AMBIGUOUS).
    ``quality``: [0, 1], method specific (1 = perfect fit).
    Fields that do not exist for a failed estimate are ``None``.
    """

    method: str
    status: Status
    reason: str = ""
    psi_deg: float | None = None
    bearing_deg: float | None = None
    yaw_enu_deg: float | None = None
    sigma_deg: float | None = None
    pixels: int = 0
    quality: float = 0.0
    axial: bool = False
    sun_altitude_deg: float | None = None      # implied by the data (least squares), a consistency check
    extras: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """A usable heading (possibly axial)."""
        return self.status in (Status.OK, Status.AMBIGUOUS) and self.psi_deg is not None

    @staticmethod
    def failed(method: str, status: Status, reason: str, pixels: int = 0, **extras) -> "HeadingResult":
        return HeadingResult(method, status, reason, pixels=int(pixels), extras=dict(extras))

    @staticmethod
    def from_psi(method: str, psi_deg: float, sun_azimuth_deg: float, sigma_deg: float, pixels: int,
                 quality: float, axial: bool, reason: str = "", **kw) -> "HeadingResult":
        """Fill bearing and REP-103 yaw from psi; refuses non-finite numbers (raises, a bug). ``sigma_deg``
        None: not computed (``estimate(obs, sigma=False)``)."""
        psi_deg, sun_azimuth_deg, quality = float(psi_deg), float(sun_azimuth_deg), float(quality)
        for name, v in (("psi_deg", psi_deg), ("sigma_deg", sigma_deg), ("quality", quality)):
            if v is not None and not math.isfinite(v):
                raise FloatingPointError(f"{method}: non-finite {name} reached a result")
        if not math.isfinite(sun_azimuth_deg):
            bearing = float(psi_to_bearing_deg(psi_deg, sun_azimuth_deg))      # nan, as before
        else:
            bearing = _wrap_360(psi_deg + sun_azimuth_deg)
        return HeadingResult(method, Status.AMBIGUOUS if axial else Status.OK, reason,
                             _wrap_180(psi_deg), bearing, _wrap_180(90.0 - bearing),
                             None if sigma_deg is None else float(sigma_deg), int(pixels),
                             min(max(quality, 0.0), 1.0), bool(axial), **kw)

    def to_json_dict(self) -> dict:
        d = asdict(self)
        d["status"] = self.status.value
        return d


@dataclass
class Observation:
    """What an estimator sees. Images may be 2-D (a grid) or 1-D (a pixel list); all share a shape.

    ``aop_rad`` eq 28 convention; ``rays_cam`` (3, N) float32 unit rays in the order of
    ``aop_rad.reshape(-1)``; ``x_px``/``y_px`` 1-based eq 20 coordinates. The sun (azimuth clockwise
    from North, geometric altitude) comes from the ephemeris; it turns psi into a bearing and flags
    sun-at-zenith / below-horizon cases. ``pitch_deg``/``roll_deg`` are the known tilt (tilt_aware),
    ``prior_bearing_deg`` an optional prior that resolves the 180 deg ambiguity.
    """

    aop_rad: np.ndarray
    dop: np.ndarray
    valid: np.ndarray
    rays_cam: np.ndarray
    x_px: np.ndarray
    y_px: np.ndarray
    camera: CameraModel
    sun_azimuth_deg: float
    sun_altitude_deg: float
    intensity: np.ndarray | None = None
    pitch_deg: float | None = None
    roll_deg: float | None = None
    prior_bearing_deg: float | None = None

    @staticmethod
    def from_frame(frame, pitch_deg=None, roll_deg=None, prior_bearing_deg=None, camera=None) -> "Observation":
        """From a :class:`~polarization_compass.render.Frame` (measured AoP/DoP when sensor effects ran)."""
        from ..scene import Scene  # noqa: F401  (documentation of origin)
        cam = camera if camera is not None else CameraModel(**frame.meta["camera"]) if "camera" in frame.meta \
            else CameraModel()
        return Observation(frame.aop_rad, frame.dop, frame.valid, frame.rays_cam, frame.x_px, frame.y_px, cam,
                           frame.sun.azimuth_deg, frame.sun.altitude_deg, frame.intensity,
                           pitch_deg, roll_deg, prior_bearing_deg)


class Estimator:
    """Base class. Subclasses set ``name`` and ``axial`` and implement :meth:`estimate`.

    ``knobs`` trade accuracy for time (stride, region, min_dop, window ...); ``pixels_needed`` tells a
    renderer which pixels this method reads, so sweeps render only those.

    ``sigma_optional``: the method accepts ``estimate(obs, sigma=False)``, which skips the uncertainty
    (``sigma_deg`` None, no residual statistics in ``extras``) for callers that use only psi and status
    (error-map sweeps). psi is the same as with ``sigma=True`` except that an unresolved (axial) result
    may name the other end of the meridian, which it does not know anyway; status and quality are the same.
    """

    name = "base"
    axial = True
    sigma_optional = False

    def __init__(self, **knobs):
        self.knobs = dict(knobs)

    def pixels_needed(self, camera: CameraModel) -> PixelSelection:
        return PixelSelection.full()

    def estimate(self, obs: Observation) -> HeadingResult:  # pragma: no cover - interface
        """One heading. Methods with ``sigma_optional`` also take ``sigma: bool = True``."""
        raise NotImplementedError


_REGISTRY: dict[str, Callable[..., Estimator]] = {}


def register_estimator(name: str):
    def deco(cls):
        cls.name = name
        _REGISTRY[name] = cls
        return cls
    return deco


def estimator_names() -> list[str]:
    """The registered methods, in the paper's order, then the others."""
    from . import methods  # noqa: F401  (registers on import)
    order = ["zenith", "sm_asm", "symmetry", "least_squares", "tilt_aware"]
    return [n for n in order if n in _REGISTRY] + sorted(set(_REGISTRY) - set(order))


def estimator_knob_names(name: str) -> frozenset:
    """Names of the knobs method ``name`` accepts (empty for an estimator without a knob table)."""
    from . import methods  # noqa: F401
    if name not in _REGISTRY:
        raise EstimatorError(f"unknown method {name!r}; known: {', '.join(estimator_names())}")
    specs = getattr(_REGISTRY[name], "knob_specs", None)
    return frozenset(specs()) if specs is not None else frozenset()


def make_estimator(name: str, **knobs) -> Estimator:
    from . import methods  # noqa: F401
    if name not in _REGISTRY:
        raise EstimatorError(f"unknown method {name!r}; known: {', '.join(estimator_names())}")
    return _REGISTRY[name](**knobs)
