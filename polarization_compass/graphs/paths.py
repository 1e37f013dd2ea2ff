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

"""Where a graph's files and executables are: the share directory and the node commands."""

from __future__ import annotations

import os
from pathlib import Path
import shutil
import sys

from .spec import GraphError, PACKAGE


def node_command(executable: str) -> list[str]:
    """
    Return the command that starts one of the package's node executables outside ``ros2 launch``.

    The console script next to this interpreter (a venv's ``bin``) when it is there, else one on
    ``PATH``, else ``python -m polarization_compass.nodes.<executable>``: on a ROS install the
    scripts live in ``install/lib/polarization_compass``, which is on neither, and the module form
    runs the same ``main``.

    Parameters
    ----------
    executable : str
        Node executable name as in ``setup.py``'s console scripts (e.g. ``"heading_estimator"``).

    Returns
    -------
    list of str
        The argv prefix; append ``--ros-args ...``.

    """
    here = Path(sys.executable).parent / executable
    if here.is_file() and os.access(here, os.X_OK):
        return [str(here)]
    found = shutil.which(executable)
    if found:
        return [found]
    return [sys.executable, '-m', f'{PACKAGE}.nodes.{executable}']


# ------------------------------------------------------------------------------------------------
# Where the parameter files are
# ------------------------------------------------------------------------------------------------
def share_dir() -> Path:
    """
    Return the package's share directory (``config/``, ``launch/``).

    ``POLARIZATION_COMPASS_SHARE`` if set; else the source tree when this is a source checkout
    (same layout); else the colcon install found through the ament index.

    Returns
    -------
    pathlib.Path
        The directory.

    Raises
    ------
    GraphError
        None of them is found.

    """
    env = os.environ.get('POLARIZATION_COMPASS_SHARE')
    if env:
        return Path(env)
    src = Path(__file__).resolve().parents[2]
    if (src / 'config').is_dir() and (src / 'setup.py').is_file():
        return src  # a source checkout (or an editable install of one)
    try:
        from ament_index_python.packages import get_package_share_directory, PackageNotFoundError

        try:
            return Path(get_package_share_directory(PACKAGE))
        except (PackageNotFoundError, LookupError, ValueError):
            pass
    except ImportError:
        pass
    raise GraphError(
        'cannot find the polarization_compass share directory (config/, launch/): install the '
        'package with colcon or set POLARIZATION_COMPASS_SHARE'
    )
