"""polarization_compass: heading from skylight polarization, with tilt error maps and correction.

The core library (this package minus ``nodes``) is ROS-free and works on numpy arrays.
"""
__version__ = "0.1.0"
