"""Progress bars for long steps (rich), silent when asked or not on a terminal."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import TypeVar

T = TypeVar("T")


def progress_enabled() -> bool:
    """Bars are shown on an interactive stderr unless FTCAL_PROGRESS=0."""
    flag = os.environ.get("FTCAL_PROGRESS")
    if flag is not None:
        return flag not in ("0", "false", "no")
    return sys.stderr.isatty()


_ACTIVE: list = []  # the Progress display on screen, if any: nested bars become its rows


@contextmanager
def progress_bar(description: str, total: float | None):
    """Yield an ``advance(n)`` callable that moves a bar (or does nothing).

    A bar opened while another is on screen (e.g. a statistics pass inside the whole search)
    becomes a row of the same display, removed when it ends: one live display at a time.
    """
    if not progress_enabled():
        yield lambda n=1: None
        return
    if _ACTIVE:
        bar = _ACTIVE[-1]
        task = bar.add_task(description, total=total)
        try:
            yield lambda n=1: bar.advance(task, n)
        finally:
            bar.remove_task(task)
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    columns = [TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TimeElapsedColumn(), TimeRemainingColumn()]
    with Progress(*columns, console=Console(stderr=True), transient=False) as bar:
        task = bar.add_task(description, total=total)
        _ACTIVE.append(bar)
        try:
            yield lambda n=1: bar.advance(task, n)
        finally:
            _ACTIVE.pop()


def track(items: Iterable[T], description: str, total: int | None = None) -> Iterator[T]:
    """Iterate ``items`` with a progress bar."""
    if total is None and hasattr(items, "__len__"):
        total = len(items)  # type: ignore[arg-type]
    with progress_bar(description, total) as advance:
        for item in items:
            yield item
            advance(1)
