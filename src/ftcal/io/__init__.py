"""Readers and writers: tables, robot logs, model files."""
