"""Registers every heading estimator (imported by :mod:`.base` on first use of the registry)."""
from . import least_squares  # noqa: F401  (least_squares, tilt_aware)
from . import sm_asm  # noqa: F401
from . import symmetry  # noqa: F401
from . import zenith  # noqa: F401
