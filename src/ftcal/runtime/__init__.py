"""The floor everything stands on: errors and warnings, argument checks, threads, progress,
executors (in process or Dask), worker processes that always stop, and atomic writes.

Owns how work runs and how it fails, nothing about sensors. Imports nothing of ftcal
outside this package; every other package may import it.
"""
