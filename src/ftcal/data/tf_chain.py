"""A tf tree: frames joined by static and time-stamped rotations, composed along a chain.

ROS convention (REP 105, tf2): a ``TransformStamped`` with ``header.frame_id``
= parent and ``child_frame_id`` = child holds the child frame's pose in the
parent frame, so its rotation R_parent_child maps child-frame vectors into the
parent frame. The orientation of SENSOR in BASE is the product of the
rotations along the chain BASE → … → SENSOR (an edge walked from child to
parent contributes its inverse). Only rotations matter for orientation, so
translations are not kept. Dynamic edges are interpolated with slerp; times
outside the span every dynamic edge on the chain covers are dropped.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from ..runtime.errors import FtcalError, ParameterError
from .recording import Stream

QUATERNION_COLUMNS = ("qx", "qy", "qz", "qw")
# A quaternion further than this from unit norm is a logging error, not rounding.
UNIT_NORM_TOLERANCE = 1e-3


class TransformTree:
    """Rotations between frames, as read from /tf and /tf_static.

    Parameters
    ----------
    where : str
        Names the source in error messages (e.g. ``"Bag run.bag"``).
    """

    def __init__(self, where: str) -> None:
        self.where = where
        self._static: dict[tuple[str, str], tuple[float, tuple[float, ...]]] = {}
        self._dynamic: dict[tuple[str, str], list[tuple[float, tuple[float, ...]]]] = {}

    def add(self, parent: str, child: str, time: float, quaternion: tuple[float, ...], static: bool) -> None:
        """Record R_parent_child at ``time`` (s) as quaternion (x, y, z, w); checked when a chain uses it."""
        if static:
            self._static[(parent, child)] = (time, tuple(quaternion))
        else:
            self._dynamic.setdefault((parent, child), []).append((time, tuple(quaternion)))

    def frames(self) -> list[str]:
        """Every frame named by a transform, sorted."""
        return sorted({f for edge in (*self._static, *self._dynamic) for f in edge})

    def _check_tree(self) -> None:
        """Refuse a tf graph that is not a tree: a frame with two parents, or a loop of frames.

        tf allows one parent per frame; with two, which chain is meant is ambiguous
        and picking one silently would give a wrong orientation.
        """
        parents: dict[str, str] = {}
        for parent, child in (*self._static, *self._dynamic):
            if parents.setdefault(child, parent) != parent:
                first, second = sorted((parents[child], parent))
                raise FtcalError(f"{self.where}: tf frame {child!r} has two parents, {first!r} and {second!r}; "
                                 "a tf tree gives each frame one parent.")
        for start in parents:
            seen = [start]
            while (up := parents.get(seen[-1])) is not None:
                if up in seen:
                    loop = " -> ".join(seen[seen.index(up):] + [up])
                    raise FtcalError(f"{self.where}: tf frames form a loop ({loop}); a tf tree has none.")
                seen.append(up)

    def chain(self, base: str, frame: str) -> list[tuple[str, str, bool]]:
        """Edges (parent, child, walked_backwards) from ``base`` to ``frame``.

        Raises
        ------
        FtcalError
            If a frame is unknown or the two are not connected; the message lists the known frames.
        """
        self._check_tree()
        neighbours: dict[str, list[tuple[str, tuple[str, str, bool]]]] = {}
        for parent, child in (*self._static, *self._dynamic):
            neighbours.setdefault(parent, []).append((child, (parent, child, False)))
            neighbours.setdefault(child, []).append((parent, (parent, child, True)))
        previous: dict[str, tuple[str, tuple[str, str, bool]] | None] = {base: None}
        queue = deque([base])
        while queue:
            here = queue.popleft()
            for there, edge in neighbours.get(here, ()):
                if there not in previous:
                    previous[there] = (here, edge)
                    queue.append(there)
        if base not in neighbours or frame not in previous:
            known = ", ".join(self.frames()) or "none"
            raise ParameterError(('joints_topic', 'urdf'), f"{self.where}: no tf chain from {base!r} to {frame!r} (frames known: {known}); "
                             "without one, record the joints: {joints_topic} with {urdf} gives the orientation "
                             "from the robot model.")
        edges = []
        while (step := previous[frame]) is not None:
            frame, edge = step
            edges.append(edge)
        return edges[::-1]

    def orientation_stream(self, base: str, frame: str, times: np.ndarray, name: str) -> Stream:
        """Orientation of ``frame`` in ``base`` at ``times`` (s) inside the span the chain covers.

        Returns
        -------
        Stream
            Columns ``qx, qy, qz, qw`` (rotation from ``frame`` to ``base``), at the subset of ``times``
            that every dynamic edge of the chain covers.

        Raises
        ------
        FtcalError
            No chain, or no time in ``times`` inside the span of the chain's dynamic edges.
        """
        from scipy.spatial.transform import Rotation, Slerp

        edges = [] if base == frame else self.chain(base, frame)
        lo, hi = -np.inf, np.inf
        samples = {}
        for parent, child, _ in edges:
            static = (parent, child) not in self._dynamic
            t, q = _sorted_unique([self._static[(parent, child)]] if static else self._dynamic[(parent, child)])
            if not np.all(np.isfinite(q)):
                k = int(np.argmax(~np.isfinite(q).all(axis=1)))
                raise FtcalError(f"{self.where}: tf {parent}->{child} at t={t[k]:.6f} s has a non-finite quaternion.")
            check_unit_quaternions(q, t, f"{self.where}: tf {parent}->{child}")
            samples[(parent, child)] = (t, q)
            if not static:
                lo, hi = max(lo, t[0]), min(hi, t[-1])
        keep = (times >= lo) & (times <= hi)
        if not keep.any():
            raise FtcalError(f"{self.where}: the tf chain {base}->{frame} covers t={lo:.3f}..{hi:.3f} s, "
                             f"which does not overlap the F/T stream (t={times[0]:.3f}..{times[-1]:.3f} s).")
        at = times[keep]
        rotation = Rotation.identity(at.size)
        for parent, child, backwards in edges:
            t, q = samples[(parent, child)]
            if t.size > 1:
                step = Slerp(t, Rotation.from_quat(q))(at)
            else:
                step = Rotation.from_quat(np.tile(q[0], (at.size, 1)))
            rotation = rotation * (step.inv() if backwards else step)
        return Stream(name, at, rotation.as_quat(), QUATERNION_COLUMNS, clock="tf composed at the F/T stamps")


def check_unit_quaternions(q: np.ndarray, time: np.ndarray, where: str) -> None:
    """Raise :class:`FtcalError` unless every finite row of ``q`` (n, 4) has unit norm."""
    norm = np.linalg.norm(q, axis=1)
    bad = np.isfinite(norm) & (np.abs(norm - 1.0) > UNIT_NORM_TOLERANCE)
    if bad.any():
        k = int(np.argmax(bad))
        raise FtcalError(f"{where}: quaternion at t={time[k]:.6f} s has norm {norm[k]:.6g}, not 1 "
                         f"({int(bad.sum())} such sample(s)).")


def _sorted_unique(samples: list[tuple[float, tuple[float, ...]]]) -> tuple[np.ndarray, np.ndarray]:
    """Times ascending, one sample per time (the last one logged wins)."""
    t = np.array([s[0] for s in samples])
    q = np.array([s[1] for s in samples])
    order = np.argsort(t, kind="stable")
    t, q = t[order], q[order]
    last = np.r_[t[1:] != t[:-1], True]
    return t[last], q[last]
