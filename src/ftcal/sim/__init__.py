"""Simulation and the demos: simulated strain-gauge sensors, trajectories, robot-logger
recordings, a UR5-like arm writing ROS bags, and the two ``ftcal demo`` scenarios
(``demo``: the paper's experiment end to end; ``demo_arm``: bag → payload → compensation).

The top application layer below the CLI: may import every other package except
:mod:`ftcal.cli`.
"""
