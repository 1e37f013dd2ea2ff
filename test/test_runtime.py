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

"""The process plumbing of :mod:`polarization_compass.runtime`."""


def test_kernels_run_single_threaded_during_replay_and_settings_come_back():
    import numba
    from polarization_compass.runtime import openblas_handles as _openblas_handles
    from polarization_compass.runtime import single_threaded_kernels

    before = numba.get_num_threads()
    assert _openblas_handles(), "numpy's OpenBLAS not found"
    blas_before = [g() for _, g in _openblas_handles()]
    with single_threaded_kernels():
        assert numba.get_num_threads() == 1
        assert all(g() == 1 for _, g in _openblas_handles())
    assert numba.get_num_threads() == before
    assert [g() for _, g in _openblas_handles()] == blas_before
