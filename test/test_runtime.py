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
    """
    Numba and every loaded OpenBLAS run one thread in the context; their counts come back after.

    BLAS is first set to 2 threads (the suite runs with OPENBLAS_NUM_THREADS=1, which alone could
    not tell a restore from a no-op); the counts are read with threadpoolctl's own report and each
    library's ``openblas_get_num_threads`` through ctypes, independently of the code under test.
    """
    import ctypes

    import numba
    from polarization_compass.runtime import single_threaded_kernels
    import scipy.linalg  # noqa: F401 - loads scipy's OpenBLAS beside numpy's
    from threadpoolctl import threadpool_info, threadpool_limits

    def blas_threads():
        """Return (threadpoolctl's count, the library's own) for each loaded OpenBLAS."""
        out = []
        for lib in threadpool_info():
            if lib['internal_api'] == 'openblas':
                so = ctypes.CDLL(lib['filepath'])
                name = next(
                    f'{prefix}_get_num_threads{suffix}'
                    for prefix in ('scipy_openblas', 'openblas')
                    for suffix in ('64_', '')
                    if hasattr(so, f'{prefix}_get_num_threads{suffix}')
                )
                out.append((lib['num_threads'], getattr(so, name)()))
        return out

    before = numba.get_num_threads()
    with threadpool_limits(limits=2, user_api='blas'):
        assert blas_threads() and all(t == (2, 2) for t in blas_threads()), blas_threads()
        with single_threaded_kernels():
            assert numba.get_num_threads() == 1
            assert all(t == (1, 1) for t in blas_threads()), blas_threads()
        assert numba.get_num_threads() == before
        assert all(t == (2, 2) for t in blas_threads()), blas_threads()
