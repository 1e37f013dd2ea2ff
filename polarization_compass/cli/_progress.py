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

"""Progress bars of the long subcommands: tqdm on stderr, off when stderr is not a terminal."""

from __future__ import annotations

import sys


def progress_bar(desc: str, unit: str, total: int | None = None):
    """
    Open a tqdm progress bar on stderr; disabled when stderr is not a terminal.

    Parameters
    ----------
    desc : str
        What is being done, shown before the bar (the subcommand's name).
    unit : str
        What is counted.
    total : int, optional
        How many there will be (None: a counter with a rate, no ETA).

    Returns
    -------
    tqdm.tqdm
        The bar; ``advance_to(bar, k)`` moves it to ``k`` done. Close it when done.

    """
    from tqdm import tqdm

    return tqdm(
        total=total,
        desc=desc,
        unit=unit,
        file=sys.stderr,
        dynamic_ncols=True,
        disable=not sys.stderr.isatty(),
    )


def advance_to(bar, done: int, total: int | None = None) -> None:
    """
    Move a bar to ``done`` items (callbacks report counts, tqdm counts increments).

    Parameters
    ----------
    bar : tqdm.tqdm
        The bar.
    done : int
        Items done so far.
    total : int, optional
        The total, when the callback learns it only now.

    """
    if total is not None and bar.total != total:
        bar.total = total
    if done > bar.n:
        bar.update(done - bar.n)
