"""Execution order: each load mounted once, short joint travel, regular returns to a reference pose.

Within a load, the poses form an open path from the reference pose, built by
nearest neighbour and shortened by 2-opt (joint-space Euclidean distance, rad).
The reference pose is visited at the start of each load, after every ``every``
poses and at the end, so a drifting bias shows as a change between visits
instead of hiding in the payload (systematic orders make the two collinear).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

# 2-opt passes over the whole path at most (each pass is O(n²) distance checks).
MAX_TWO_OPT_PASSES = 50


@dataclass(frozen=True)
class Step:
    """One row of the plan: ``pose`` indexes the designed poses, or is -1 for the reference pose."""

    pose: int
    load: int

    @property
    def reference(self) -> bool:
        return self.pose < 0


def _path_length(points: np.ndarray, path: Sequence[int]) -> float:
    return float(np.linalg.norm(np.diff(points[list(path)], axis=0), axis=1).sum())


def short_path(points: np.ndarray, start: np.ndarray) -> list[int]:
    """An open path through all ``points`` (n, d) from ``start`` (d,): nearest neighbour, then 2-opt.

    Returns
    -------
    list of the indices of ``points`` in visiting order.
    """
    n = points.shape[0]
    if n == 0:
        return []
    left = list(range(n))
    here = start
    path: list[int] = []
    while left:
        dist = np.linalg.norm(points[left] - here, axis=1)
        nxt = left.pop(int(np.argmin(dist)))
        path.append(nxt)
        here = points[nxt]
    # 2-opt on the path with the start as a fixed first node (node 0); the path's end is free.
    nodes = np.vstack([start[None, :], points])
    dist = np.linalg.norm(nodes[:, None, :] - nodes[None, :, :], axis=2)
    route = [0] + [i + 1 for i in path]
    for _ in range(MAX_TWO_OPT_PASSES):
        improved = False
        for i in range(1, len(route) - 1):
            for j in range(i + 1, len(route)):
                a, b, c = route[i - 1], route[i], route[j]
                d = route[j + 1] if j + 1 < len(route) else None
                before = dist[a, b] + (dist[c, d] if d is not None else 0.0)
                after = dist[a, c] + (dist[b, d] if d is not None else 0.0)
                if after < before - 1e-12:
                    route[i:j + 1] = route[i:j + 1][::-1]
                    improved = True
        if not improved:
            break
    return [k - 1 for k in route[1:]]


def execution_order(joints: np.ndarray, loads: np.ndarray, reference: np.ndarray, every: int,
                    load_order: Sequence[int]) -> list[Step]:
    """Order the designed poses for execution.

    Parameters
    ----------
    joints : ndarray of shape (n, d), the moving joints of each designed pose (rad)
    loads : ndarray of shape (n,), the load index of each pose
    reference : ndarray of shape (d,), the reference pose
    every : int >= 1, designed poses between two visits of the reference pose
    load_order : the order in which loads are mounted (loads without poses are skipped)

    Returns
    -------
    list of Step: per load, the reference pose, then the poses with the reference
    pose after every ``every`` of them and at the end.
    """
    steps: list[Step] = []
    for load in load_order:
        members = np.flatnonzero(loads == load)
        if members.size == 0:
            continue
        path = members[short_path(joints[members], reference)]
        steps.append(Step(-1, int(load)))
        for k, pose in enumerate(path, start=1):
            steps.append(Step(int(pose), int(load)))
            if k % every == 0 or k == len(path):
                steps.append(Step(-1, int(load)))
    return steps


def travel(joints: np.ndarray, reference: np.ndarray, steps: Sequence[Step]) -> float:
    """Total joint-space travel (rad, Euclidean) of ``steps``."""
    points = np.array([reference if s.reference else joints[s.pose] for s in steps])
    return _path_length(points, range(len(points)))
