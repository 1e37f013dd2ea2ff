"""Heading estimators: the paper's four approaches plus an exact tilt-aware least-squares solve."""
from .base import (EstimatorError, HeadingResult, Observation, Status, estimator_knob_names,  # noqa: F401
                   estimator_names, make_estimator)
