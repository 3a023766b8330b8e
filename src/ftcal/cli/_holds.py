"""``ftcal payload``'s data checks: drop the moving samples before a static identification; the excitation."""

from __future__ import annotations


class StaticRows:
    """The ``select`` of :func:`ftcal.payload.tables.table_statistics`: the static rows of each table.

    Motion is read from the ``--orientation`` quaternions, else from the joint
    columns of a robot model, else from the gravity direction, over the
    ``--time`` column; a table without that column keeps the samples its
    ``static`` column marks still (written by ``ftcal dataset``), else is used
    whole (said in :attr:`notes`). ``notes``: one line per table for the printout.
    """

    def __init__(self, args, source) -> None:
        self.args = args
        self.source = source
        self.notes: list[str] = []

    def __call__(self, frame, kinematics, path: str):
        from pathlib import Path

        import numpy as np

        from ..data.holds import MIN_HOLD_S, find_holds
        from ..data.tables import numeric_columns
        from ..runtime.errors import FtcalError

        args = self.args
        time_column = args.time or "time"
        if time_column not in frame.columns and "static" in frame.columns:
            # The marks `ftcal dataset` wrote (data.holds, from the same signals), for a table without its clock.
            marks = numeric_columns(frame, ("static",), Path(path), "static")[:, 0]
            if not np.all((marks == 0) | (marks == 1)):
                raise FtcalError(f"{path}: column 'static' must hold 1 (still) or 0 (moving).")
            static = marks == 1
            if not static.any():
                raise FtcalError(f"{path}: column 'static' marks no sample still; give --keep-moving to use "
                                 "every sample.")
            moving = int(static.size - np.count_nonzero(static))
            self.notes.append(f"{path}: no time column {time_column!r}: its 'static' column marks {moving} of "
                              f"{static.size} samples moving; " + ("excluded" if moving else "all used")
                              + " (--keep-moving keeps them)")
            return static
        if time_column not in frame.columns:
            self.notes.append(f"{path}: no time column {time_column!r}: all {len(frame)} samples used as static "
                              "(give --time COL to find and drop the moving ones)")
            return None
        time = numeric_columns(frame, (time_column,), Path(path), "time")[:, 0]
        segments = frame["segment"].to_numpy() if "segment" in frame.columns else None
        signal = {}
        if args.orientation is not None:
            signal["orientation"] = numeric_columns(frame, args.orientation, Path(path), "orientation")
        elif getattr(args, "robot_urdf", None) is not None or getattr(args, "robot_model", None) is not None:
            names = set(self.source.columns)
            joints = numeric_columns(frame, [c for c in frame.columns if c in names], Path(path), "joint")
            signal["joints"] = np.deg2rad(joints) if args.degrees else joints
        else:
            signal["gravity"] = kinematics.gravity
        holds = find_holds(time, segments=segments, where=path, time_column=time_column, **signal)
        if not holds.static.any():
            raise FtcalError(f"{path}: no static hold of {MIN_HOLD_S:g} s or more (every sample moves, from the "
                             f"{holds.signal}); record still poses, or give --keep-moving to use every sample.")
        self.notes.append(f"{path}: {holds.describe(time)}; "
                          + ("excluded" if holds.n_moving else "all used") + " (--keep-moving keeps them)")
        return holds.static


def payload_excitation(groups) -> str:
    """One line: the relative singular values of the payload regressor, and how many directions they determine."""
    from ..core.excitation import regressor_excitation

    total = None
    for stats in groups.values():
        total = stats if total is None else total + stats
    singular, n_determined = regressor_excitation(total.gram())
    return (f"excitation: the poses determine {n_determined} of {len(singular)} parameter directions (relative "
            f"singular values of the payload regressor, columns scaled to unit norm: "
            f"{', '.join(f'{v:.2g}' for v in singular)})")
