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
Whole-sky samples for the whole-sky check: of a live mosaic, or of a whole image's observation.

:func:`whole_sky_sample` reads every k-th 2 x 2 block of a full-sensor mosaic and its sky rays
(the nodes and the replay); :func:`observation_sky_sample` samples the observation of a whole
image (``estimate`` on real images).
"""

from __future__ import annotations

import numpy as np

from ..camera import CameraModel
from ..polarizer_check import decimated_blocks

__all__ = [
    'decimated_blocks',
    'observation_sky_sample',
    'whole_sky_sample',
]


def whole_sky_sample(mosaic, camera: CameraModel, layout, max_blocks: int = 8000):
    """
    Sample the whole usable sky of a full-sensor mosaic, whatever pixels a method reads.

    Superpixels of a block decimation; saturated blocks and their glare removed; intensity kept for
    the whole-sky side vote.

    Parameters
    ----------
    mosaic : numpy.ndarray
        Raw full-sensor DoFP image.
    camera : CameraModel
        The camera (rays cached per intrinsics and grid).
    layout : MosaicLayout
        The polarizer layout.
    max_blocks : int, default 8000
        Blocks demosaiced at most.

    Returns
    -------
    SkySample or None
        The :class:`~polarization_compass.skyfit.SkySample`, None when too little sky is usable.

    """
    from ..demosaic import aop_dop_from_stokes, stokes_from_mosaic
    from ..estimators.mosaic_input import _grid_rays
    from ..polarizer_check import saturated_blocks
    from ..skyfit import data_mask, sample_sky

    m = np.asarray(mosaic)
    small, k, nx, ny = decimated_blocks(m, max_blocks)
    sat = float(np.iinfo(m.dtype).max) if np.issubdtype(m.dtype, np.integer) else None
    s0, s1, s2 = stokes_from_mosaic(
        small, layout.angles_deg, layout.pol45_toward, 'superpixel', sat
    )
    aop, dop, valid = aop_dop_from_stokes(s0, s1, s2)
    _, _, rays, has_ray = _grid_rays(camera, (1.5, 2.0 * k, nx), (1.5, 2.0 * k, ny))
    bright = np.where(saturated_blocks(small, sat, s0.shape), np.float32(np.inf), s0)
    keep = data_mask(bright, has_ray, float('inf'))
    return sample_sky(aop, dop, valid & keep, rays, s0)


def observation_sky_sample(obs):
    """
    Sample the usable sky of an observation of a whole image.

    Parameters
    ----------
    obs : Observation
        The whole image's observation (:func:`.real_image.real_observation`), intensity included.

    Returns
    -------
    SkySample or None
        The :class:`~polarization_compass.skyfit.SkySample`, None when too little sky is usable.

    """
    from ..skyfit import sample_sky

    return sample_sky(obs.aop_rad, obs.dop, obs.valid, obs.rays_cam, obs.intensity)
