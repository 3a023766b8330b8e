"""The default column names, in a module without imports so the command line can name them cheaply."""

DEFAULT_INPUTS = ("u1", "u2", "u3", "u4", "u5", "u6", "T")  # raw channels, then temperature (°C)
DEFAULT_OUTPUTS = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")  # N, N·m
# The label columns `ftcal dataset` writes: the load case's name (validation groups never split one; its old
# spelling "group" is still read, with a notice) and the recording's number (ARX lags never cross one).
LOAD_COLUMN, OLD_LOAD_COLUMN = "load", "group"
SEGMENT_COLUMN = "segment"
