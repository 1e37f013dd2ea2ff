"""What the lens adds: the sun and its glare in the field, lens-flare ghosts, vignetting.

A scene declares these under ``optics`` (each key optional; nothing undeclared is constructed or run,
and each stage that runs is counted in :mod:`polarization_compass.instrumentation`)::

    optics:
      sun:        {disk_radiance: 2.0e5, glare_at_1deg: 30.0, glare_exponent: 2.0}
      flare:      {positions: [-0.37, -0.63, -0.83, -1.11], radius_px: 18, radiance: 0.6}
      vignetting: {law: cos4}  |  {k: [k1, k2, k3]}

All radiances are relative to the clear-sky zenith (the radiance models' unit). Light the lens adds
is unpolarized: where it adds ``G`` to a pixel of radiance ``I`` the DoP becomes ``DoP I / (I + G)``
and the AoP is unchanged. A scene with a sensor ``exposure`` then saturates where the sum exceeds the
full well (the demosaic marks those pixels invalid), as the sun does in real frames.

Sun and glare
-------------
The solar disk (angular radius 0.2666 deg, the mean apparent semi-diameter) has radiance
``disk_radiance`` (the sun's luminance, ~1.6e9 cd/m^2, over a clear sky's ~8e3: about 2e5). Around it
the lens's veiling glare falls as a power of the angle gamma from the sun,
``glare_at_1deg * (1 deg / gamma) ** glare_exponent`` for gamma > the disk radius, the form of the
Stiles-Holladay disability-glare law (exponent 2; CIE 135/1-1999, Vos & van den Berg) that a lens's
point-spread wings also follow.

Lens-flare ghosts
-----------------
Internal reflections image the sun to ghosts on the line through the sun's image point ``s`` and the
optical centre ``c`` (the principal point): ghost k is centred on ``c + t_k (s - c)``, a disk of
``radius_px`` with radiance ``radiance``. The default positions ``t`` are measured on the real frame
``sunny.jpg`` (``../shared/data/real-sky/README.md``: sun at (762, 1750), centre (1076.3, 1000.9),
ghosts at (1194, 726), (1272, 518), (1336, 373), (1427, 171): t = -0.37, -0.63, -0.83, -1.11).
Ghosts exist only while the sun projects into the image (its ray in front of a pinhole or inside a
fisheye's field).

Vignetting
----------
``law: cos4``: natural vignetting of a thin lens, irradiance ~ cos^4(theta) of the angle from the
optical axis (e.g. Kingslake, "Optical System Design", 1983). ``k: [k1, k2, k3]``: the radial
polynomial ``V = 1 + k1 r^2 + k2 r^4 + k3 r^6`` of the distance r from the principal point over the
half-diagonal (Goldman 2010, "Vignette and exposure calibration and compensation", IEEE TPAMI 32).
The radiance is multiplied by V; the DoP and AoP are unchanged.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .errors import CompassError

__all__ = ["OpticsError", "Optics", "SUN_SEMIDIAMETER_DEG", "REAL_FRAME_GHOST_POSITIONS", "ghost_centres_px"]

SUN_SEMIDIAMETER_DEG = 0.2666
#: Ghost positions t along sun -> centre measured on the real frame sunny.jpg (module docstring).
REAL_FRAME_GHOST_POSITIONS = (-0.37, -0.63, -0.83, -1.11)


class OpticsError(CompassError):
    """A scene's ``optics`` mapping that cannot be used; the message names the key."""


def _num(v, name, lo, hi):
    if isinstance(v, bool):
        raise OpticsError(f"optics.{name} must be a number, got {v!r}")
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise OpticsError(f"optics.{name} must be a number, got {v!r}") from None
    if not math.isfinite(f) or not (lo <= f <= hi):
        raise OpticsError(f"optics.{name} must be finite and in [{lo}, {hi}], got {v!r}")
    return f


def _keys(d, allowed, where):
    if not isinstance(d, dict):
        raise OpticsError(f"optics.{where} must be a mapping, got {type(d).__name__}")
    unknown = set(d) - set(allowed)
    if unknown:
        raise OpticsError(f"unknown key(s) {sorted(unknown)} in optics.{where}; allowed: {sorted(allowed)}")


@njit(parallel=True, cache=True, fastmath=True)
def _optics_kernel(rays, x, y, use_xy, vig_mode, cx, cy, inv_hd2, k1, k2, k3, do_sun, sx, sy, sz, cos_disk, disk,
                   g1, expo, gx, gy, r2, grad, dop, inten):  # pragma: no cover - compiled
    """All declared lens effects in one pass (float32): vignetting (mode 1 cos^4, 2 radial polynomial)
    multiplies the radiance; the sun disk, its glare and the ghosts add unpolarized light."""
    one = np.float32(1.0)
    zero = np.float32(0.0)
    one_deg = np.float32(math.pi / 180.0)
    disk_rad = np.float32(math.acos(cos_disk))
    for i in prange(rays.shape[1]):
        px = rays[0, i]
        py = rays[1, i]
        pz = rays[2, i]
        xi = np.float32(0.0)
        yi = np.float32(0.0)
        if use_xy:
            xi = np.float32(x[i])
            yi = np.float32(y[i])
        v = one
        if vig_mode == 1:
            z = max(pz, zero)
            v = z * z * z * z
        elif vig_mode == 2:
            q = ((xi - cx) * (xi - cx) + (yi - cy) * (yi - cy)) * inv_hd2
            v = one + q * (k1 + q * (k2 + q * k3))
        base = inten[i] * v
        g = zero
        # branch-free below (selects, not ifs): such loops vectorise; branchy ones ran several times slower
        if do_sun:
            c = min(max(sx * px + sy * py + sz * pz, -one), one)
            gam = max(math.acos(c), disk_rad)
            glare = g1 * math.exp(expo * math.log(one_deg / gam))
            g = disk if c >= cos_disk else glare
        for k in range(gx.size):
            dx = xi - gx[k]
            dy = yi - gy[k]
            g += grad if dx * dx + dy * dy <= r2 else zero
        tot = base + g
        dop[i] = dop[i] * (base / tot) if g > zero else dop[i]
        inten[i] = tot


def ghost_centres_px(sun_px, centre_px, positions):
    """Ghost centres (k, 2) px on the line through the sun's image point and the optical centre:
    ``c + t_k (s - c)``."""
    s = np.asarray(sun_px, dtype=float)
    c = np.asarray(centre_px, dtype=float)
    t = np.asarray(positions, dtype=float).reshape(-1, 1)
    return c + t * (s - c)


class Optics:
    """The declared lens effects of a scene, applied in the order vignetting (to the sky), sun, flare."""

    def __init__(self, cfg: dict, camera):
        _keys(cfg, {"sun", "flare", "vignetting"}, "")
        self.camera = camera
        self.sun = self.flare = self.vignetting = None
        if cfg.get("sun") is not None:
            s = cfg["sun"]
            _keys(s, {"disk_radiance", "glare_at_1deg", "glare_exponent"}, "sun")
            self.sun = {"disk_radiance": _num(s.get("disk_radiance", 2.0e5), "sun.disk_radiance", 0.0, 1e9),
                        "glare_at_1deg": _num(s.get("glare_at_1deg", 30.0), "sun.glare_at_1deg", 0.0, 1e9),
                        "glare_exponent": _num(s.get("glare_exponent", 2.0), "sun.glare_exponent", 0.5, 6.0)}
        if cfg.get("flare") is not None:
            f = cfg["flare"]
            _keys(f, {"positions", "radius_px", "radiance"}, "flare")
            pos = f.get("positions", list(REAL_FRAME_GHOST_POSITIONS))
            if not isinstance(pos, (list, tuple)) or not 1 <= len(pos) <= 32:
                raise OpticsError("optics.flare.positions must be a list of 1-32 numbers (t along sun -> centre)")
            self.flare = {"positions": [_num(t, "flare.positions", -10.0, 10.0) for t in pos],
                          "radius_px": _num(f.get("radius_px", 18.0), "flare.radius_px", 0.5, 5000.0),
                          "radiance": _num(f.get("radiance", 0.6), "flare.radiance", 0.0, 1e9)}
        if cfg.get("vignetting") is not None:
            v = cfg["vignetting"]
            _keys(v, {"law", "k"}, "vignetting")
            if ("law" in v) == ("k" in v):
                raise OpticsError("optics.vignetting needs either law: cos4 or k: [k1, k2, k3]")
            if "law" in v:
                if v["law"] != "cos4":
                    raise OpticsError(f"optics.vignetting.law must be 'cos4', got {v['law']!r}")
                self.vignetting = {"law": "cos4"}
            else:
                k = v["k"] if isinstance(v["k"], (list, tuple)) else [v["k"]]
                if not 1 <= len(k) <= 3:
                    raise OpticsError("optics.vignetting.k must be 1-3 numbers [k1, k2, k3]")
                ks = [_num(x, "vignetting.k", -10.0, 10.0) for x in k]
                r = np.linspace(0.0, 1.0, 101)
                if (1.0 + sum(c * r ** (2 * (j + 1)) for j, c in enumerate(ks))).min() <= 0.0:
                    raise OpticsError("optics.vignetting.k gives a non-positive falloff inside the image")
                self.vignetting = {"k": ks}

    @property
    def stages(self) -> list[str]:
        return [n for n in ("vignetting", "sun", "flare") if getattr(self, n) is not None]

    def params(self) -> dict:
        return {n: dict(getattr(self, n)) for n in self.stages}

    def sun_px(self, sun_cam):
        """The sun's image point (x, y) px, or None when it does not project into the lens' field."""
        s = np.asarray(sun_cam, dtype=float).reshape(3, 1)
        cam = self.camera
        if cam.model == "pinhole":
            if s[2, 0] <= 1e-6:
                return None
        elif math.degrees(math.acos(min(1.0, max(-1.0, s[2, 0])))) > cam.max_field_angle_deg:
            return None
        x, y = cam.pixels_from_rays(s)
        return float(x[0]), float(y[0])

    def apply(self, sun_cam, rays_cam, x_px, y_px, aop, dop, intensity, instr) -> None:
        """The declared lens effects on the flat arrays (in place; intensity float32 writable), in one fused
        kernel; each declared stage is counted."""
        f32 = np.float32
        vig_mode, ks = 0, (0.0, 0.0, 0.0)
        if self.vignetting is not None:
            instr.count("optics.vignetting")
            if "law" in self.vignetting:
                vig_mode = 1
            else:
                vig_mode = 2
                ks = tuple(self.vignetting["k"]) + (0.0,) * (3 - len(self.vignetting["k"]))
        s = np.asarray(sun_cam, dtype=float)
        s = s / np.linalg.norm(s)
        p = self.sun or {"disk_radiance": 0.0, "glare_at_1deg": 0.0, "glare_exponent": 2.0}
        if self.sun is not None:
            instr.count("optics.sun")
        gx = gy = np.empty(0, np.float32)
        r2 = grad = 0.0
        if self.flare is not None:
            instr.count("optics.flare")
            sp = self.sun_px(sun_cam)
            if sp is not None:
                g = ghost_centres_px(sp, (self.camera.cx_px, self.camera.cy_px), self.flare["positions"])
                gx, gy = np.ascontiguousarray(g[:, 0], np.float32), np.ascontiguousarray(g[:, 1], np.float32)
                r2, grad = self.flare["radius_px"] ** 2, self.flare["radiance"]
        use_xy = vig_mode == 2 or gx.size > 0
        x = np.asarray(x_px).reshape(-1) if use_xy else np.empty(1)
        y = np.asarray(y_px).reshape(-1) if use_xy else np.empty(1)
        cam = self.camera
        _optics_kernel(np.ascontiguousarray(rays_cam, dtype=np.float32), x, y, use_xy, vig_mode, f32(cam.cx_px),
                       f32(cam.cy_px), f32(4.0 / (cam.width_px ** 2 + cam.height_px ** 2)), f32(ks[0]), f32(ks[1]),
                       f32(ks[2]), self.sun is not None, f32(s[0]), f32(s[1]), f32(s[2]),
                       f32(math.cos(math.radians(SUN_SEMIDIAMETER_DEG))), f32(p["disk_radiance"]),
                       f32(p["glare_at_1deg"]), f32(p["glare_exponent"]), gx, gy, f32(r2), f32(grad), dop, intensity)
