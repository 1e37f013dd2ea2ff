"""Photodiode-array polarization compasses (POL-OP units): a few units, each behind 2-4 linear
polarizers, looking at a known direction of the sky.

- :mod:`.geometry`  the sensor description (YAML) and its validation;
- :mod:`.readings`  recordings (``.npz`` / CSV: samples x units x channels);
- :mod:`.stokes`    per-unit Stokes vector, angle and degree of polarization from the channels;
- :mod:`.heading`   heading from the units' E-vectors (least squares / tilt aware);
- :mod:`.calibrate` relative channel gains from the data itself;
- :mod:`.simulate`  simulated readings under a Rayleigh sky (tests, scenes).

How a unit's polarizer angles map to the body frame is owned by :mod:`..conventions`
(:func:`~polarization_compass.conventions.unit_evector_body`).
"""
from .geometry import ArrayGeometry, ArrayGeometryError, UnitGeometry, load_array_geometry

__all__ = ["ArrayGeometry", "ArrayGeometryError", "UnitGeometry", "load_array_geometry"]
