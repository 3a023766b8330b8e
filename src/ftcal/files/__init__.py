"""Every file ftcal writes for people and robots, and reads back: the native JSON model and
payload files (versioned schemas, sha256), the paper's XML, the iCub firmware matrix and
WBD parameters, generated C99, ONNX and ROS YAML.

Reading and writing one format live in one module; ``targets`` is the ``ftcal convert``
registry (target name → writer) and ``model_files`` the suffix → model reader table.
Nothing heavy is imported by this package itself. May import :mod:`ftcal.payload`,
:mod:`ftcal.data`, :mod:`ftcal.core` and :mod:`ftcal.runtime`.
"""
