"""Simulated sensors, trajectories and robot-logger recordings (no robot needed)."""
