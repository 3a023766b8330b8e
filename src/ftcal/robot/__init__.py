"""Robot models and expected F/T wrenches (iDynTree).

:class:`RobotModel` loads a URDF (a path, or an iCub by name), attaches
payloads and lists the six-axis F/T sensors (also declared on plain URDFs,
:mod:`ftcal.robot.declare`); :func:`expected_wrenches` predicts what every F/T
sensor should measure for given joint data; :mod:`ftcal.robot.kinematics` gives
sensor-frame gravity and motion and the regressor of an unknown payload. The output
convention (frame, sign) is documented in :mod:`ftcal.robot.expected`.

May import :mod:`ftcal.payload` (its regressor, for the joint-data route to payload
identification), :mod:`ftcal.core` and :mod:`ftcal.runtime`.
"""

from .declare import SensorDeclaration
from .expected import FloatingBase, WrenchPredictor, expected_wrenches
from .loadcases import LoadCase, LoadCaseConfig, load_case_config
from .model import FTSensor, RobotModel
from .payloads import Payload, parse_payload_spec

__all__ = ["FTSensor", "FloatingBase", "LoadCase", "LoadCaseConfig", "Payload", "RobotModel",
           "SensorDeclaration", "WrenchPredictor", "expected_wrenches", "load_case_config", "parse_payload_spec"]
