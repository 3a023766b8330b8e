"""Payload and bias identification: the inertial regressor, gravity and motion sources,
the fit (bias, mass, centre of mass, optional inertia) with honest standard errors, a bias
that drifts in time or temperature (``drift``: linear, random walk), compensation of
readings, re-taring, and calibration with an unknown load (``unknown_load``).

May import :mod:`ftcal.data`, :mod:`ftcal.core` and :mod:`ftcal.runtime`; the robot-model
route to its kinematics lives in :mod:`ftcal.robot.kinematics`, above it.
"""
