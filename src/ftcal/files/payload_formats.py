"""Writers for payload files (``format: "ftcal-payload"``), in the registry's writer contract.

Each adapter hands a loaded payload to :mod:`ftcal.files.ros_yaml` with the
options its format uses.
"""

from __future__ import annotations

from pathlib import Path

from ..payload.identify import describe_parameters
from ..payload.parameters import PayloadParameters
from .ros_yaml import DEFAULT_COM_FRAME, write_ft_tools_ros2, write_ros_yaml
from .targets import ConvertOptions, Written


def _notes(source: PayloadParameters) -> tuple[str, ...]:
    """What the target files cannot say: parameters the identification poses did not determine."""
    if source.undetermined is None:
        return ()
    return (f"{describe_parameters(source.undetermined.parameters)} not determined by the identification poses: "
            f"exported at the payload file's convention ({describe_parameters(source.undetermined.held)} held at 0), "
            "right only in poses like the recorded ones",)


def write_force_torque_tools(source: PayloadParameters, output: Path, options: ConvertOptions) -> Written:
    """force_torque_tools ``ft_calib`` YAML (``--frame`` names the COM frame's parent when the file has none)."""
    return Written((write_ros_yaml(source, output, frame=options.get("frame"),
                                   com_frame=options.get("com_frame", DEFAULT_COM_FRAME)),), _notes(source))


def write_ft_tools_ros2_yaml(source: PayloadParameters, output: Path, options: ConvertOptions) -> Written:
    """ft_tools_ros2 ``calibration.yaml``."""
    return Written((write_ft_tools_ros2(source, output),), _notes(source))
