"""Readers and writers: tables, robot logs, ROS bags, model files."""
