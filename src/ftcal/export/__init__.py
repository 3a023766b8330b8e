"""Robot-side artefacts from model (and payload) files: the ``ftcal convert`` targets.

:mod:`ftcal.export.targets` is the registry (target name → writer); each target
that is not one of the :mod:`ftcal.io` model formats is one module here
(:mod:`~ftcal.export.c_code`, :mod:`~ftcal.export.onnx_graph`). Nothing heavy is
imported by this package itself, so the CLI can list targets cheaply.
"""
