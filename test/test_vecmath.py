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
The branch-free float64 math of the vectorised kernels, and their vectorisation.

The math (polarization_compass.fastmath) is checked against numpy's libm; the SM-ASM and Symmetry
pass loops that use it stay vectorised (LLVM emits vector instructions for them).
"""

import math
import re

from numba import njit
import numpy as np
from polarization_compass import fastmath as vm
import pytest


@njit(cache=False)
def _map2(f_id, a, b, out0, out1):
    for i in range(a.size):
        if f_id == 0:
            out0[i], out1[i] = vm.sincos(a[i])
        elif f_id == 1:
            out0[i], out1[i] = vm.sincos_folded(a[i])
        elif f_id == 2:
            out0[i] = vm.atan2(a[i], b[i])
        else:
            out0[i] = vm.exp_nonpos(a[i])


def _run(f_id, a, b=None):
    o0, o1 = np.empty_like(a), np.empty_like(a)
    _map2(f_id, a, a if b is None else b, o0, o1)
    return o0, o1


def test_sincos_matches_libm_over_many_turns():
    rng = np.random.default_rng(0)
    a = np.concatenate(
        [
            rng.uniform(-200.0, 200.0, 200_000),
            np.arange(-64, 65) * (math.pi / 2),
            [0.0, -0.0, 1e-300, math.pi, -math.pi],
        ]
    )
    s, c = _run(0, a)
    assert np.abs(s - np.sin(a)).max() < 1e-13  # the reduction a - n pi costs n ulp(pi)
    assert np.abs(c - np.cos(a)).max() < 1e-13
    small = np.abs(a) < 4.0
    assert (
        np.abs(s - np.sin(a))[small].max() < 2e-15 and np.abs(c - np.cos(a))[small].max() < 2e-15
    )


def test_sincos_folded_is_sincos_up_to_one_sign():
    rng = np.random.default_rng(1)
    a = rng.uniform(-50.0, 50.0, 100_000)
    s, c = _run(1, a)
    sign = np.where(np.rint(a / math.pi) % 2 == 0, 1.0, -1.0)
    assert (
        np.abs(s - sign * np.sin(a)).max() < 1e-13 and np.abs(c - sign * np.cos(a)).max() < 1e-13
    )
    # what the kernels use it for: cos 2a, sin 2a without the sign
    assert np.abs((c * c - s * s) - np.cos(2 * a)).max() < 1e-13
    assert np.abs(2 * s * c - np.sin(2 * a)).max() < 1e-13


def test_atan2_matches_libm_in_every_octant_and_scale():
    rng = np.random.default_rng(2)
    n = 400_000
    y = rng.normal(size=n) * 10.0 ** rng.uniform(-9, 9, n)
    x = rng.normal(size=n) * 10.0 ** rng.uniform(-9, 9, n)
    axes = np.array([1.0, -1.0, 0.0, 3.0, -3.0])
    y = np.concatenate([y, axes, np.zeros(5) + 2.0, [1.0, 1.0, -1.0, -1.0]])
    x = np.concatenate([x, np.zeros(5), axes * 0.5, [1.0, -1.0, 1.0, -1.0]])
    got, _ = _run(2, y, x)
    assert np.abs(got - np.arctan2(y, x)).max() < 1e-15
    assert _run(2, np.zeros(1), np.zeros(1))[0][0] == 0.0  # no NaN at the origin


def test_exp_nonpos_relative_error_and_clip():
    rng = np.random.default_rng(3)
    x = np.concatenate(
        [
            -rng.uniform(0.0, 700.0, 300_000),
            -rng.uniform(0.0, 1e-3, 1000),
            [0.0, -0.0, -1e-300, -700.0, -math.log(2.0) / 2],
        ]
    )
    got, _ = _run(3, x)
    assert np.max(np.abs(got - np.exp(x)) / np.exp(x)) < 2e-15
    edge, _ = _run(3, np.array([-800.0, -1e6, 5.0]))
    np.testing.assert_allclose(edge, [math.exp(-700.0), math.exp(-700.0), 1.0], rtol=2e-15)


@pytest.mark.parametrize('name', ['_band_terms', '_ring_terms', '_band_sums', '_ring1_terms'])
def test_disc_pass_loops_are_vectorised(name):
    """
    The per-pixel loops of the SM-ASM and Symmetry passes compile to vector code.

    A libm call, a select inside a reduction or a Python-model division check would each make LLVM
    keep the loops scalar (2-3x slower). Compiled afresh from the Python source with the kernel's
    own options (cached code has no IR).
    """
    from polarization_compass.estimators import _sm_asm_kernels, _symmetry_kernels

    disp = getattr(_sm_asm_kernels if name.startswith('_band') else _symmetry_kernels, name)
    fresh = njit(
        **{k: v for k, v in disp.targetoptions.items() if k not in ('cache', 'nopython')}
    )(disp.py_func)
    f32, b = np.zeros(64, np.float32), np.ones(64, bool)
    rays = np.zeros((3, 64), np.float32)
    s = np.array([0.0, 0.5, 0.8])
    if name == '_band_terms':
        fresh(
            f32,
            f32,
            b,
            rays,
            0.0,
            1.0,
            0.2,
            8.0,
            1.0,
            0.5,
            s,
            s,
            np.ones(64),
            True,
            np.empty(64),
            np.empty(64),
            np.zeros(2),
        )
    elif name == '_ring_terms':
        z = np.empty(64)
        fresh(
            f32,
            f32,
            b,
            rays,
            0,
            64,
            0.0,
            0.05,
            1.0,
            0.2,
            8,
            s,
            s,
            np.ones(64),
            True,
            z,
            z.copy(),
            z.copy(),
            z.copy(),
            z.copy(),
            z.copy(),
            np.zeros(2),
        )
    elif name == '_band_sums':
        fresh(f32, f32, b, rays, 0.0, 1.0, 0.2, 8.0, np.zeros(3), np.zeros(4, np.int64))
    else:
        z = np.empty(64)
        fresh(
            f32,
            f32,
            b,
            rays,
            0,
            64,
            0.0,
            0.05,
            1.0,
            0.2,
            8,
            z,
            z.copy(),
            z.copy(),
            z.copy(),
            z.copy(),
            np.zeros(4, np.int64),
        )
    ir = ''.join(fresh.inspect_llvm().values())
    assert '"llvm.loop.isvectorized"' in ir and re.search(r'<\d+ x double>', ir), (
        f'{name}: not vectorised'
    )
    libm = set(
        re.findall(r'call [^\n(]*@((?:llvm\.)?(?:exp|atan2|atan|cos|sin|pow|log)\b[.\w]*)\(', ir)
    )
    assert not libm, f'{name}: libm calls (one scalar call per lane) {sorted(libm)}'


@pytest.mark.parametrize('name', ['_gather_lanes', '_level_rss2'])
def test_disc_helper_loops_are_vectorised(name):
    """
    The gathers' pixel loader and the level-residual pass compile to vector code.

    The loader uses no fast-math (the same values as a scalar loop); the level-residual pass is
    that of sm_asm and symmetry. Compiled afresh with the kernel's own options, as above.
    """
    from polarization_compass.estimators import _disc

    disp = getattr(_disc, name)
    fresh = njit(
        **{k: v for k, v in disp.targetoptions.items() if k not in ('cache', 'nopython')}
    )(disp.py_func)
    f32, b = np.zeros(64, np.float32), np.ones(64, bool)
    rays = np.zeros((3, 64), np.float32)
    if name == '_gather_lanes':
        fresh(
            f32,
            f32,
            b,
            rays,
            0,
            64,
            0.0,
            0.0,
            1.0,
            0.2,
            np.empty(64, np.int8),
            np.empty(64),
            np.empty((6, 64)),
        )
    else:
        fresh(f32, f32, b, rays, 0.0, 0.0, 1.0, 0.0, 0.5, 0.8, 0.1, 0.2, 0.9, 3, np.zeros(3))
    ir = ''.join(fresh.inspect_llvm().values())
    assert '"llvm.loop.isvectorized"' in ir and re.search(r'<\d+ x double>', ir), (
        f'{name}: not vectorised'
    )
