"""The sizes of the C core's rings, declared once in ``csrc/ftcal_live.h`` (``FTCAL_LIVE_DRIFT_SNAPSHOTS``,
``FTCAL_LIVE_SC_KEEP_HOLDS``, ``FTCAL_LIVE_SC_WALK_KEEP``) and read here from its text: the Python self-check keeps
as many holds and hold starts as the C, the generated header names them, and :func:`ftcal.live.core.require_core`
checks that the extension was built from this text. Numpy-free; no compiler needed.
"""

from __future__ import annotations

import re
from pathlib import Path

HEADER = Path(__file__).parent / "csrc" / "ftcal_live.h"
NAMES = ("DRIFT_SNAPSHOTS", "SC_KEEP_HOLDS", "SC_WALK_KEEP")


def _read() -> dict[str, int]:
    text = HEADER.read_text(encoding="utf-8")
    found = dict(re.findall(r"^#define FTCAL_LIVE_([A-Z_]+) (\d+)\b", text, flags=re.MULTILINE))
    missing = [n for n in NAMES if n not in found]
    if missing:  # a damaged installation, not a user's input
        raise RuntimeError(f"{HEADER.name} does not declare FTCAL_LIVE_{missing[0]}")
    return {n: int(found[n]) for n in NAMES}


CORE_LIMITS = _read()
DRIFT_SNAPSHOTS = CORE_LIMITS["DRIFT_SNAPSHOTS"]
SC_KEEP_HOLDS = CORE_LIMITS["SC_KEEP_HOLDS"]
SC_WALK_KEEP = CORE_LIMITS["SC_WALK_KEEP"]
