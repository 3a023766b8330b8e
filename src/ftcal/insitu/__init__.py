"""In-situ datasets: robot recordings (logs or ROS bags) plus a robot model and its load
cases become a :class:`~ftcal.core.dataset.Dataset` of raw readings and expected wrenches.

``recordings`` handles robot logs (the paper's route), ``bags`` ROS bags with tf or joint
states. May import :mod:`ftcal.robot`, :mod:`ftcal.payload`, :mod:`ftcal.data`,
:mod:`ftcal.core` and :mod:`ftcal.runtime`.
"""
