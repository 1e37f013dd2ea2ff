"""Tilt error maps: the heading error of each method over sun altitude x yaw x pitch x roll (paper, section 3).

A map holds, for every method m and grid cell (sun altitude h, yaw psi, pitch alpha, roll beta),

    error_deg[m, h, psi, alpha, beta] = fold_axial(estimated psi - true psi)   in (-90, 90] deg

computed by rendering a scene with the sun fixed at azimuth 0 and altitude h and the camera at
bearing psi (so bearing == psi, :mod:`~polarization_compass.conventions`), pitch alpha and roll beta,
then running the method on the pixels it reads (``estimator.pixels_needed(camera)``) and nothing else.

Arrays of an :class:`ErrorMap` (and of the ``.npz`` file, loaded with ``allow_pickle=False``):

``error_deg``        float64 (methods, sun altitudes, yaws, pitches, rolls). Never NaN: cells without a
                     usable estimate hold 0 and are flagged by ``status``/``valid``.
``status``           int8, same shape: :data:`STATUS_CODES` (0 ok, 1 ok but axial, >= 2 the estimator's
                     failure status, -1 not computed (outside the tilt domain), -2 the estimator raised).
``valid``            bool, same shape: status is 0 or 1 (the error is meaningful).
``methods``          unicode (methods,)
``sun_altitude_deg``, ``yaw_deg``, ``pitch_deg``, ``roll_deg``: float64 strictly increasing axes.
``meta``             0-d unicode array, JSON: scene, sampling (per-method pixel selection and knobs),
                     domain rule, status legend, package version, format version.

The tilt domain: the paper keeps |pitch| + |roll| <= 30 deg (a 108 deg field of view above the horizon).
By default a (pitch, roll) node is computed when it is a corner of a grid cell that touches that
diamond, so that every point with |pitch| + |roll| <= 30 can be interpolated from computed nodes (the
nodes one grid step outside the diamond are computed; everything further out is skipped).
``full_domain=True`` computes every node.

Sweeps run in chunks of one (sun altitude, pitch) pair each, on all cores (``multiprocessing``, spawn,
numba limited to one thread per worker), with a tqdm progress bar on stderr. Each finished chunk is
checkpointed to ``<out>.partial/``; an interrupted sweep rerun with the same arguments continues where it
stopped and gives the same map (noise seeds are a function of the cell, not of the order of work).
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import sys
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .conventions import CameraAttitude, fold_axial_deg
from .errors import CompassError

__all__ = ["ErrorMap", "ErrorMapError", "SweepSpec", "parse_range", "run_sweep", "load_error_map",
           "tilt_domain_mask", "STATUS_CODES", "STATUS_NOT_COMPUTED", "STATUS_ESTIMATOR_ERROR",
           "DEFAULT_TILT_LIMIT_DEG", "FORMAT_VERSION"]

FORMAT_VERSION = 1
DEFAULT_TILT_LIMIT_DEG = 30.0

#: int8 status codes stored in a map (by the estimator's Status *value*, so the table is stable).
STATUS_CODES = {"ok": 0, "ambiguous": 1, "sun_near_zenith": 2, "sun_below_horizon": 3, "too_few_pixels": 4,
                "out_of_domain": 5, "bad_input": 6, "degenerate": 7, "insufficient_coverage": 9}
STATUS_NOT_COMPUTED = -1
STATUS_ESTIMATOR_ERROR = -2
STATUS_OTHER = 8          # a status value this table does not know (a newer estimator)
_STATUS_LEGEND = {**{str(v): k for k, v in STATUS_CODES.items()}, str(STATUS_NOT_COMPUTED): "not_computed",
                  str(STATUS_ESTIMATOR_ERROR): "estimator_error", str(STATUS_OTHER): "other"}



class ErrorMapError(CompassError):
    """A bad sweep specification, or an error-map file that is missing, corrupt or inconsistent."""


# --------------------------------------------------------------------------------------------
# Axes
# --------------------------------------------------------------------------------------------
def parse_range(text: str, name: str = "range", lo: float = -math.inf, hi: float = math.inf,
                max_count: int = 100000) -> np.ndarray:
    """``"A:B:STEP"`` (inclusive of B when B - A is a multiple of STEP) or a single value ``"A"``.

    Returns a float64 strictly increasing array. Raises :class:`ErrorMapError` with the reason.
    """
    parts = str(text).split(":")
    try:
        nums = [float(p) for p in parts]
    except ValueError:
        raise ErrorMapError(f"--{name} must be A:B:STEP or a single number, got {text!r}") from None
    if not all(math.isfinite(v) for v in nums):
        raise ErrorMapError(f"--{name} must be finite, got {text!r}")
    if len(nums) == 1:
        values = np.array(nums)
    elif len(nums) == 3:
        a, b, step = nums
        if step <= 0:
            raise ErrorMapError(f"--{name}: STEP must be > 0, got {step}")
        if b < a:
            raise ErrorMapError(f"--{name}: B must be >= A, got {text!r}")
        n = int(math.floor((b - a) / step + 1e-9)) + 1
        if n > max_count:
            raise ErrorMapError(f"--{name}: {n} values is more than {max_count}")
        values = a + step * np.arange(n)
        values = np.round(values, 9)          # 0.1 * 3 -> 0.3, not 0.30000000000000004
    else:
        raise ErrorMapError(f"--{name} must be A:B:STEP or a single number, got {text!r}")
    if values.min() < lo or values.max() > hi:
        raise ErrorMapError(f"--{name} values must lie in [{lo}, {hi}], got {text!r}")
    return values.astype(float)


def _min_abs_on(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """min |x| over the interval [lo, hi] (elementwise)."""
    return np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(np.abs(lo), np.abs(hi)))


def tilt_domain_mask(pitch_deg, roll_deg, limit_deg: float = DEFAULT_TILT_LIMIT_DEG,
                     support: int = 0) -> np.ndarray:
    """(pitches, rolls) bool: which (pitch, roll) nodes lie in, or support, the tilt domain.

    ``support=0``: exactly the nodes with |pitch| + |roll| <= limit. ``support=1``: also every node
    that is a corner of a grid cell touching that region (what multilinear interpolation inside it
    reads). ``support=2``: also the nodes one step further (what cubic interpolation reads).
    """
    p = np.asarray(pitch_deg, dtype=float)
    r = np.asarray(roll_deg, dtype=float)
    eps = 1e-9
    k = int(support)
    if k < 0:
        raise ErrorMapError(f"support must be >= 0, got {support}")

    def neighbourhood(axis):
        # min |x| over [axis[i - k], axis[i + k]] (clipped to the axis)
        n = axis.size
        i = np.arange(n)
        return _min_abs_on(axis[np.clip(i - k, 0, n - 1)], axis[np.clip(i + k, 0, n - 1)])

    return (neighbourhood(p)[:, None] + neighbourhood(r)[None, :]) <= limit_deg + eps


# --------------------------------------------------------------------------------------------
# The map
# --------------------------------------------------------------------------------------------
AXES = ("sun_altitude_deg", "yaw_deg", "pitch_deg", "roll_deg")


@dataclass
class ErrorMap:
    """A computed error map (see the module docstring for the arrays' meaning)."""

    error_deg: np.ndarray
    status: np.ndarray
    methods: tuple
    sun_altitude_deg: np.ndarray
    yaw_deg: np.ndarray
    pitch_deg: np.ndarray
    roll_deg: np.ndarray
    meta: dict = field(default_factory=dict)

    @property
    def valid(self) -> np.ndarray:
        return (self.status == STATUS_CODES["ok"]) | (self.status == STATUS_CODES["ambiguous"])

    @property
    def shape(self) -> tuple:
        return self.error_deg.shape

    def axes(self) -> tuple:
        return (self.sun_altitude_deg, self.yaw_deg, self.pitch_deg, self.roll_deg)

    def method_index(self, method: str) -> int:
        try:
            return list(self.methods).index(method)
        except ValueError:
            raise ErrorMapError(f"method {method!r} is not in this map (it has {', '.join(self.methods)})") \
                from None

    @staticmethod
    def axis_index(axis: np.ndarray, value: float, name: str, tol: float = 1e-6) -> int:
        """Index of the node equal to ``value`` (within ``tol``); :class:`ErrorMapError` if none."""
        i = int(np.argmin(np.abs(axis - value)))
        if abs(axis[i] - value) > tol:
            raise ErrorMapError(f"{name} {value:g} is not a node of the map's {name} axis "
                                f"({_axis_text(axis)})")
        return i

    def validate(self) -> "ErrorMap":
        """Check shapes, axes, finiteness and status codes; raises :class:`ErrorMapError`."""
        axes = self.axes()
        for name, a in zip(AXES, axes):
            if a.ndim != 1 or a.size < 1:
                raise ErrorMapError(f"{name} must be a non-empty 1-D axis, got shape {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ErrorMapError(f"{name} has NaN or inf values")
            if a.size > 1 and not np.all(np.diff(a) > 0):
                raise ErrorMapError(f"{name} must be strictly increasing")
        want = (len(self.methods),) + tuple(a.size for a in axes)
        if self.error_deg.shape != want:
            raise ErrorMapError(f"error_deg has shape {self.error_deg.shape}, the axes say {want}")
        if self.status.shape != want:
            raise ErrorMapError(f"status has shape {self.status.shape}, the axes say {want}")
        if self.error_deg.dtype.kind != "f" or not np.all(np.isfinite(self.error_deg)):
            raise ErrorMapError("error_deg must be finite floating point (no NaN/inf)")
        if np.any(np.abs(self.error_deg) > 90.0 + 1e-9):
            raise ErrorMapError("error_deg values must be folded to (-90, 90]")
        known = set(STATUS_CODES.values()) | {STATUS_NOT_COMPUTED, STATUS_ESTIMATOR_ERROR, STATUS_OTHER}
        if self.status.dtype.kind not in "iu" or not np.all(np.isin(self.status, list(known))):
            raise ErrorMapError("status holds unknown codes")
        if len(set(self.methods)) != len(self.methods) or not all(isinstance(m, str) and m for m in self.methods):
            raise ErrorMapError("methods must be distinct non-empty names")
        if self.sun_altitude_deg.min() < -90 or self.sun_altitude_deg.max() > 90:
            raise ErrorMapError("sun_altitude_deg must lie in [-90, 90]")
        return self

    def save(self, path, float32: bool = False) -> Path:
        """Write the map as a compressed ``.npz`` (atomically: a temporary file, then rename).

        ``float32`` halves the file (errors keep ~1e-5 deg); loading always gives float64.
        """
        self.validate()
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp = p.with_name(p.name + ".tmp.npz")
        err = self.error_deg.astype(np.float32) if float32 else self.error_deg
        np.savez_compressed(tmp, error_deg=err, status=self.status.astype(np.int8),
                            valid=self.valid, methods=np.array(self.methods, dtype=str),
                            sun_altitude_deg=self.sun_altitude_deg, yaw_deg=self.yaw_deg,
                            pitch_deg=self.pitch_deg, roll_deg=self.roll_deg,
                            meta=np.array(json.dumps(self.meta, sort_keys=True)))
        os.replace(tmp, p)
        return p


def _axis_text(a: np.ndarray) -> str:
    if a.size == 1:
        return f"{a[0]:g}"
    return f"{a[0]:g}..{a[-1]:g}, {a.size} nodes"


def load_error_map(path) -> ErrorMap:
    """Load and validate a map written by :meth:`ErrorMap.save`. Raises :class:`ErrorMapError` (never
    unpickles)."""
    p = Path(path)
    if not p.is_file():
        raise ErrorMapError(f"error map {str(p)!r} does not exist")
    try:
        # np.load leaks its file handle when the zip is corrupt: own the handle here
        with open(p, "rb") as fh:
            z = np.load(fh, allow_pickle=False)
            if not isinstance(z, np.lib.npyio.NpzFile):       # a bare .npy array under an .npz name
                raise ErrorMapError(f"{p}: not an error map (a single array, not an .npz archive)")
            with z:
                missing = [k for k in ("error_deg", "status", "methods", *AXES, "meta") if k not in z.files]
                if missing:
                    raise ErrorMapError(f"{p}: not an error map (missing {', '.join(missing)})")
                arrays = {k: z[k] for k in ("error_deg", "status", "methods", *AXES, "meta")}
    except ErrorMapError:
        raise
    except (OSError, ValueError, zipfile.BadZipFile, EOFError, KeyError) as exc:
        raise ErrorMapError(f"{p}: corrupt or not an .npz error map ({type(exc).__name__}: {exc})") from None
    try:
        meta = json.loads(str(arrays["meta"][()]))
        if not isinstance(meta, dict):
            raise ValueError("meta is not a JSON object")
    except (ValueError, TypeError, IndexError) as exc:
        raise ErrorMapError(f"{p}: meta is not valid JSON ({exc})") from None
    methods = arrays["methods"]
    if methods.dtype.kind != "U" or methods.ndim != 1:
        raise ErrorMapError(f"{p}: methods must be a 1-D array of names")
    err = arrays["error_deg"]
    if err.dtype.kind != "f":
        raise ErrorMapError(f"{p}: error_deg must be floating point, got {err.dtype}")
    axes = []
    for k in AXES:
        a = arrays[k]
        if a.dtype.kind not in "fiu":
            raise ErrorMapError(f"{p}: {k} must be numeric, got {a.dtype}")
        axes.append(a.astype(float))
    m = ErrorMap(err.astype(float), arrays["status"], tuple(str(x) for x in methods), *axes, meta=meta)
    try:
        return m.validate()
    except ErrorMapError as exc:
        raise ErrorMapError(f"{p}: {exc}") from None


# --------------------------------------------------------------------------------------------
# Sweep specification
# --------------------------------------------------------------------------------------------
@dataclass
class SweepSpec:
    """What to compute. ``scene`` is a :class:`~polarization_compass.scene.Scene` (its attitude, sun and
    pixel selection are overridden per cell); ``knobs`` maps a method to its estimator knobs (absent: the
    estimator class's ``sweep_knobs``, chosen so that errors change by < 0.05 deg against full resolution,
    see docs/error-maps.md)."""

    methods: tuple
    sun_altitude_deg: np.ndarray
    yaw_deg: np.ndarray
    pitch_deg: np.ndarray
    roll_deg: np.ndarray
    scene: object = None
    knobs: dict = field(default_factory=dict)
    full_domain: bool = False
    tilt_limit_deg: float = DEFAULT_TILT_LIMIT_DEG
    support: int = 2

    def __post_init__(self):
        from .scene import default_scene
        if self.scene is None:
            self.scene = default_scene()
        self.methods = tuple(self.methods)
        if not self.methods:
            raise ErrorMapError("no methods to sweep")
        for name in AXES:
            a = np.atleast_1d(np.asarray(getattr(self, name), dtype=float))
            if a.size > 1 and not np.all(np.diff(a) > 0):
                raise ErrorMapError(f"{name} must be strictly increasing")
            if not np.all(np.isfinite(a)):
                raise ErrorMapError(f"{name} must be finite")
            setattr(self, name, a)
        from .estimators import registry
        self.knobs = {m: dict(self.knobs[m]) if m in self.knobs else registry.sweep_knobs(m) for m in self.methods}
        if self.scene.effects:
            self._contiguous_pixels()

    def _contiguous_pixels(self) -> None:
        """A scene with sensor effects renders a mosaic, which needs contiguous pixels (the renderer
        refuses strided selections): such sweeps read every pixel of each method's block (stride 1),
        which is slow but what a noisy frame is."""
        from .estimators import make_estimator
        cam = self.scene.camera
        for m in self.methods:
            k = self.knobs[m]
            try:
                sel = make_estimator(m, **k).pixels_needed(cam)
            except CompassError:
                continue                      # reported when the sweep builds its estimators
            if sel.mode in ("stride", "region") and sel.stride > 1:
                cand = {**k, "stride": 1}
                try:
                    make_estimator(m, **cand)
                except CompassError:
                    continue
                self.knobs[m] = cand

    @property
    def shape(self) -> tuple:
        return (len(self.methods), self.sun_altitude_deg.size, self.yaw_deg.size, self.pitch_deg.size,
                self.roll_deg.size)

    def tilt_mask(self) -> np.ndarray:
        """(pitches, rolls) bool: nodes to compute."""
        if self.full_domain:
            return np.ones((self.pitch_deg.size, self.roll_deg.size), dtype=bool)
        return tilt_domain_mask(self.pitch_deg, self.roll_deg, self.tilt_limit_deg, support=self.support)

    def chunks(self) -> list[tuple[int, int]]:
        """(sun altitude index, pitch index) pairs that have at least one node to compute."""
        mask = self.tilt_mask()
        return [(ia, ip) for ia in range(self.sun_altitude_deg.size) for ip in range(self.pitch_deg.size)
                if mask[ip].any()]

    def cell_count(self) -> int:
        """Number of (method, cell) estimates the sweep runs."""
        return int(len(self.methods) * self.sun_altitude_deg.size * self.yaw_deg.size * self.tilt_mask().sum())

    def to_meta(self) -> dict:
        from . import __version__
        return {
            "format_version": FORMAT_VERSION,
            "package_version": __version__,
            "scene": self.scene.to_dict(),
            "sampling": {m: {"knobs": self.knobs[m]} for m in self.methods},
            "domain": {"rule": "full" if self.full_domain else
                       "|pitch|+|roll| <= limit, plus the grid nodes within `support` steps of it "
                       "(what interpolation inside it reads)",
                       "tilt_limit_deg": self.tilt_limit_deg, "full_domain": self.full_domain,
                       "support": self.support},
            "sun_azimuth_deg": 0.0,
            "error_definition": "fold_axial(estimated psi - true psi), deg, in (-90, 90]; bearing == psi",
            "status_codes": _STATUS_LEGEND,
        }

    def digest(self) -> str:
        """Identifies a sweep for resuming: same digest, same cells and values."""
        meta = self.to_meta()
        meta.pop("package_version", None)
        key = {"meta": meta, "methods": list(self.methods),
               **{k: [float(x) for x in getattr(self, k)] for k in AXES}}
        return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:20]


# --------------------------------------------------------------------------------------------
# Workers
# --------------------------------------------------------------------------------------------
class _Evaluator:
    """Per-process state: one estimator per method and one renderer per distinct pixel selection.

    A noise-free cell is rendered with :meth:`Renderer.render_sky` (the sky arrays only: no Frame, no
    metadata) from attitude matrices computed for all yaws of a chunk at once; methods that read the same
    pixels share the render. (One render of the union of the selections was tried: it saves ~40 us per cell
    but is not bit for bit the same as each selection's own render when numba splits the loop over threads
    differently.) A scene with sensor effects renders full frames (the noise of a cell comes from its seed).
    Every method skips its uncertainty (``estimate(obs, sigma=False)``): a map stores psi's error and the
    status only.
    """

    def __init__(self, spec: SweepSpec):
        from .estimators import make_estimator
        from .render import Renderer
        self.spec = spec
        self.estimators = [make_estimator(m, **spec.knobs[m]) for m in spec.methods]
        camera = spec.scene.camera
        self.groups: list[tuple[object, list[int]]] = []      # (renderer, method indices)
        by_sel: dict = {}
        for i, est in enumerate(self.estimators):
            sel = est.pixels_needed(camera)
            if sel not in by_sel:
                by_sel[sel] = len(self.groups)
                self.groups.append((Renderer(spec.scene, pixels=sel), []))
            self.groups[by_sel[sel]][1].append(i)
        self.noisy = bool(spec.scene.effects)
        self.errors: list[str] = []

    def sampling(self) -> dict:
        out = {}
        for renderer, idx in self.groups:
            for i in idx:
                out[self.spec.methods[i]] = {"knobs": self.spec.knobs[self.spec.methods[i]],
                                             "pixels": renderer.selection.describe(),
                                             "pixel_count": int(renderer.pixels.count)}
        return out

    def _seed(self, ia, iy, ip, ir) -> int:
        h = hashlib.blake2b(f"{self.spec.scene.seed}:{ia}:{iy}:{ip}:{ir}".encode(), digest_size=8).digest()
        return int.from_bytes(h, "little") & 0x7FFFFFFF

    def _frames(self, sun_cam, zenith_cam):
        """(pixels, method indices, aop, dop, valid, intensity) per pixel selection for one noise-free cell."""
        out = []
        for renderer, idx in self.groups:
            aop, dop, valid, inten = renderer.render_sky(sun_cam, zenith_cam)
            shape = renderer.pixels.shape
            out.append((renderer.pixels, idx, aop.reshape(shape), dop.reshape(shape), valid.reshape(shape),
                        None if inten is None else inten.reshape(shape)))
        return out

    def _noisy_frames(self, att, sun, seed):
        """The same for a scene with sensor effects: full frames, noise from the cell's seed (the pixels are the
        frame's demosaiced ones)."""
        out = []
        for renderer, idx in self.groups:
            f = renderer.render(attitude=att, sun=sun, seed=seed)
            out.append((f.pixels, idx, f.aop_rad, f.dop, f.valid, f.intensity))
        return out

    def chunk(self, ia: int, ip: int):
        """Errors and status (methods, yaws, rolls) for sun altitude ``ia`` and pitch ``ip``."""
        from .conventions import R_enu_cam_from_attitude, enu_direction
        from .estimators.base import Observation
        from .render import SunDirection
        spec = self.spec
        camera = spec.scene.camera
        M, Y, R = len(spec.methods), spec.yaw_deg.size, spec.roll_deg.size
        err = np.zeros((M, Y, R), dtype=float)
        status = np.full((M, Y, R), STATUS_NOT_COMPUTED, dtype=np.int8)
        rolls = np.nonzero(spec.tilt_mask()[ip])[0].tolist()
        h = float(spec.sun_altitude_deg[ia])
        pitch = float(spec.pitch_deg[ip])
        sun = SunDirection(0.0, h)
        sun_enu = enu_direction(0.0, h)
        geometry = {}
        for ir in rolls:
            # bearing == psi (sun at azimuth 0): the rotations R of every yaw at once, and the camera-frame sun
            # R^T s and zenith R^T (0, 0, 1) that Renderer.render computes
            Rs = R_enu_cam_from_attitude(spec.yaw_deg, pitch, float(spec.roll_deg[ir]))
            geometry[ir] = (np.matmul(np.swapaxes(Rs, 1, 2), sun_enu), Rs[:, 2, :].copy())
        for iy, psi in enumerate(spec.yaw_deg.tolist()):
            for ir in rolls:
                roll = float(spec.roll_deg[ir])
                if self.noisy:
                    frames = self._noisy_frames(CameraAttitude(psi, pitch, roll), sun, self._seed(ia, iy, ip, ir))
                else:
                    frames = self._frames(geometry[ir][0][iy], geometry[ir][1][iy])
                for px, idx, aop, dop, valid, inten in frames:
                    obs = Observation(aop, dop, valid, px.rays_cam, px.x_px, px.y_px, camera, 0.0, h, inten,
                                      pitch, roll, None)
                    for i in idx:
                        err[i, iy, ir], status[i, iy, ir] = self._one(i, obs, psi)
        return err, status

    def _one(self, i: int, obs, psi_true: float):
        try:
            est = self.estimators[i]
            res = est.estimate(obs, sigma=False)
        except Exception as exc:  # noqa: BLE001 - one bad cell must not kill an hour-long sweep; reported
            if len(self.errors) < 5:
                self.errors.append(f"{self.spec.methods[i]}: {type(exc).__name__}: {exc}")
            return 0.0, STATUS_ESTIMATOR_ERROR
        code = STATUS_CODES.get(getattr(res.status, "value", str(res.status)), STATUS_OTHER)
        if code in (0, 1):
            if res.psi_deg is None or not math.isfinite(res.psi_deg):
                return 0.0, STATUS_ESTIMATOR_ERROR
            return fold_axial_deg(float(res.psi_deg) - psi_true), code
        return 0.0, code


_WORKER: _Evaluator | None = None
_WORKER_INIT_ERROR: BaseException | None = None


def _worker_init(spec: SweepSpec):
    # A Pool whose initializer raises respawns workers forever: keep the exception, raise it per task.
    global _WORKER, _WORKER_INIT_ERROR
    try:
        import numba
        numba.set_num_threads(1)
        _WORKER = _Evaluator(spec)
    except BaseException as exc:  # noqa: BLE001 - re-raised in _worker_chunk, i.e. in the parent
        _WORKER_INIT_ERROR = exc


def _worker_chunk(key):
    if _WORKER_INIT_ERROR is not None:
        raise _WORKER_INIT_ERROR
    ia, ip = key
    err, status = _WORKER.chunk(ia, ip)
    errors, _WORKER.errors = _WORKER.errors, []
    return ia, ip, err, status, errors


# --------------------------------------------------------------------------------------------
# Checkpoints
# --------------------------------------------------------------------------------------------
def _partial_dir(out: Path) -> Path:
    return out.with_name(out.name + ".partial")


def _chunk_path(d: Path, ia: int, ip: int) -> Path:
    return d / f"chunk_{ia:04d}_{ip:04d}.npz"


def _save_chunk(d: Path, ia, ip, err, status):
    p = _chunk_path(d, ia, ip)
    tmp = p.with_name(p.name + ".tmp.npz")
    np.savez(tmp, error_deg=err, status=status)
    os.replace(tmp, p)


def _load_chunk(d: Path, ia, ip, shape):
    p = _chunk_path(d, ia, ip)
    try:
        with open(p, "rb") as fh, np.load(fh, allow_pickle=False) as z:
            err, status = z["error_deg"], z["status"]
        if err.shape != shape or status.shape != shape or not np.all(np.isfinite(err)):
            return None
        return err, status
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError):
        return None                  # a chunk torn by a kill: recompute it


def _open_partial(d: Path, spec: SweepSpec) -> None:
    digest = spec.digest()
    stamp = d / "sweep.json"
    if d.exists():
        try:
            old = json.loads(stamp.read_text()).get("digest")
        except (OSError, ValueError):
            old = None
        if old != digest and not any(d.glob("chunk_*.npz")):
            shutil.rmtree(d)                   # nothing finished there: start afresh
        elif old != digest:
            raise ErrorMapError(f"{d} holds checkpoints of a different sweep (other arguments or scene); "
                                f"delete it or choose another --out")
        if d.exists():
            return
    d.mkdir(parents=True)
    stamp.write_text(json.dumps({"digest": digest, "shape": list(spec.shape)}))


# --------------------------------------------------------------------------------------------
# Driver
# --------------------------------------------------------------------------------------------
def run_sweep(spec: SweepSpec, out=None, workers: int | None = None, progress: bool = True,
              resume: bool = True, max_chunks: int | None = None, float32: bool = False) -> ErrorMap | None:
    """Compute the map. With ``out``, checkpoints chunks in ``<out>.partial/`` and writes ``out`` at the end.

    ``workers``: processes (default: all cores; 1 runs in this process). ``max_chunks`` stops after that
    many new chunks (tests of resuming) and returns None. A KeyboardInterrupt keeps finished chunks.
    """
    out_path = Path(out) if out is not None else None
    part = None
    if out_path is not None:
        part = _partial_dir(out_path)
        if part.exists() and not resume:
            shutil.rmtree(part)
        _open_partial(part, spec)
    M, A, Y, P, R = spec.shape
    err = np.zeros(spec.shape, dtype=float)
    status = np.full(spec.shape, STATUS_NOT_COMPUTED, dtype=np.int8)
    todo = []
    mask = spec.tilt_mask()
    for ia, ip in spec.chunks():
        got = _load_chunk(part, ia, ip, (M, Y, R)) if part is not None and _chunk_path(part, ia, ip).exists() \
            else None
        if got is None:
            todo.append((ia, ip))
        else:
            err[:, ia, :, ip, :], status[:, ia, :, ip, :] = got
    per_chunk = np.array([M * Y * int(mask[ip].sum()) for _, ip in todo])
    total = int(per_chunk.sum())
    n_workers = max(1, int(workers if workers else (os.cpu_count() or 1)))
    n_workers = min(n_workers, max(1, len(todo)))
    errors: list[str] = []
    t0 = time.perf_counter()
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=total, unit=" estimates", file=sys.stderr, dynamic_ncols=True, smoothing=0.1,
                   desc=f"errormap ({n_workers} worker{'s' if n_workers > 1 else ''})")
    limit = len(todo) if max_chunks is None else min(len(todo), int(max_chunks))
    done = 0
    sampling = None

    def accept(ia, ip, e, s, errs):
        nonlocal done
        err[:, ia, :, ip, :] = e
        status[:, ia, :, ip, :] = s
        if part is not None:
            _save_chunk(part, ia, ip, e, s)
        errors.extend(errs)
        done += 1
        if bar is not None:
            bar.update(M * Y * int(mask[ip].sum()))

    try:
        if n_workers == 1 or limit == 0:
            ev = _Evaluator(spec)
            sampling = ev.sampling()
            for ia, ip in todo[:limit]:
                e, s = ev.chunk(ia, ip)
                accept(ia, ip, e, s, ev.errors)
                ev.errors = []
        else:
            sampling = _Evaluator(spec).sampling()
            _run_pool(spec, todo[:limit], n_workers, accept)
    except KeyboardInterrupt:
        if bar is not None:
            bar.close()
        if part is not None:
            print(f"errormap: interrupted after {done} new chunk(s); finished chunks are kept in {part}; "
                  f"rerun the same command to resume", file=sys.stderr)
        raise
    if bar is not None:
        bar.close()
    if errors:
        print(f"errormap: warning: estimator exceptions (status {STATUS_ESTIMATOR_ERROR}), first: "
              + "; ".join(errors[:3]), file=sys.stderr)
    if limit < len(todo):
        return None
    meta = spec.to_meta()
    meta["sampling"] = sampling
    meta["cells_estimated"] = spec.cell_count()
    meta["elapsed_s_last_run"] = round(time.perf_counter() - t0, 3)
    meta["workers"] = n_workers
    m = ErrorMap(err, status, spec.methods, spec.sun_altitude_deg, spec.yaw_deg, spec.pitch_deg,
                 spec.roll_deg, meta)
    if out_path is not None:
        m.save(out_path, float32=float32)
        shutil.rmtree(part, ignore_errors=True)
    return m


def _run_pool(spec, todo, n_workers, accept):
    import multiprocessing as mp
    ctx = mp.get_context("spawn")      # numba's thread pool and BLAS are not fork-safe once started
    saved = {k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                                            "NUMBA_NUM_THREADS")}
    for k in saved:
        os.environ[k] = "1"            # inherited by the spawned workers only
    try:
        pool = ctx.Pool(n_workers, initializer=_worker_init, initargs=(spec,))
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    try:
        for ia, ip, e, s, errs in pool.imap_unordered(_worker_chunk, todo, chunksize=1):
            accept(ia, ip, e, s, errs)
        pool.close()
    except BaseException:
        pool.terminate()
        raise
    finally:
        pool.join()
