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
Photodiode-array polarization compasses (POL-OP units).

A few units, each behind 2-4 linear polarizers, looking at a known direction of the sky.

- :mod:`.geometry`  the sensor description (YAML) and its validation;
- :mod:`.readings`  recordings (``.npz`` / CSV: samples x units x channels);
- :mod:`.stokes`    per-unit Stokes vector, angle and degree of polarization from the channels;
- :mod:`.heading`   heading from the units' E-vectors (least squares / tilt aware);
- :mod:`.calibrate` relative channel gains from the data itself;
- :mod:`.simulate`  simulated readings under a Rayleigh sky (tests, scenes).

How a unit's polarizer angles map to the body frame is owned by :mod:`..conventions`
(:func:`~polarization_compass.conventions.unit_evector_body`).
"""

from .geometry import ArrayGeometry, ArrayGeometryError, load_array_geometry, UnitGeometry

__all__ = ['ArrayGeometry', 'ArrayGeometryError', 'UnitGeometry', 'load_array_geometry']
