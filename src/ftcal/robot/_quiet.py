"""Capture what iDynTree's C++ code prints on stderr.

iDynTree reports parse problems with ``[ERROR]``/``[WARNING]`` lines written
straight to file descriptor 2, bypassing Python. We redirect the descriptor to
a temporary file for the duration of a call, so the CLI stays one clean line
and the captured text can go into our own error message instead.
"""

from __future__ import annotations

import os
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def captured_stderr() -> Iterator[list[str]]:
    """Yield a list that receives the captured stderr lines when the block ends."""
    lines: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield lines
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            text = sink.read().decode("utf-8", errors="replace")
            lines.extend(line.strip() for line in text.splitlines() if line.strip())
