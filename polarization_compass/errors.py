"""The project's error base class. Every error meant for a user derives from :class:`CompassError`
(a ``ValueError``): the CLI prints it as one line and exits 2; nodes log, count and drop."""


class CompassError(ValueError):
    """Bad input or configuration, with a message that says what is wrong and what to do."""


class MissingDependencyError(CompassError):
    """An optional ROS piece (launch, tf2_ros, rosbag2_py, ...) is not installed here.

    Parameters
    ----------
    what : str
        The missing piece, e.g. ``"tf2_ros"``.
    install : str
        How to install it, e.g. ``"ros-jazzy-tf2-ros"``; both end up in the message and as
        attributes of the same names.
    """

    def __init__(self, what: str, install: str):
        super().__init__(f"{what} is not available: install {install}")
        self.what = what
        self.install = install
