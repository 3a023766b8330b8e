"""The one check every reader makes before it opens a file it was given.

ftcal trusts its command line but no file. Opening a FIFO blocks until a
writer appears, ``/dev/zero`` and ``/dev/urandom`` never end, a directory or a
socket is no file at all, and a symbolic-link loop never resolves: such paths
are refused here, in one line naming the path and what it is, before any
reader touches them. The size limit, when a reader has one, is checked on the
same ``stat``; the limits themselves are declared in :mod:`ftcal.core.limits`.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from .errors import FtcalError

_KINDS = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"), (stat.S_ISDIR, "a directory"))


def kind_of(mode: int) -> str:
    """What a ``stat`` mode is, in words (``"a regular file"``, ``"a FIFO (named pipe)"``, ...)."""
    return next((name for test, name in _KINDS if test(mode)), "a regular file" if stat.S_ISREG(mode)
                else "not a regular file")


def check_input_file(path: str | os.PathLike, what: str = "input file", *, folder_ok: bool = False,
                     max_bytes: int | None = None) -> Path:
    """``path`` as a :class:`Path` if it is a regular file (or, with ``folder_ok``, a directory).

    Parameters
    ----------
    path : the path the user gave
    what : what it should be, for the message (``"model file"``, ``"URDF"``, ...)
    folder_ok : accept a directory too (ROS 2 bag folders, recording folders)
    max_bytes : refuse a regular file larger than this (a limit from :mod:`ftcal.core.limits`)

    Returns
    -------
    Path

    Raises
    ------
    FtcalError
        The path does not exist, is a symbolic-link loop, cannot be inspected, is a
        FIFO, device, socket or (without ``folder_ok``) directory, or is too large.
    """
    path = Path(path)
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise FtcalError(f"{path}: no such file.") from None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise FtcalError(f"{path}: a loop of symbolic links; give the {what} itself.") from None
        raise FtcalError(f"{path}: cannot read the {what} ({exc.strerror or exc}).") from None
    except ValueError:  # an embedded NUL byte
        raise FtcalError(f"{os.fspath(path)!r}: not a valid path for the {what}.") from None
    if stat.S_ISDIR(info.st_mode) and folder_ok:
        return path
    if not stat.S_ISREG(info.st_mode):
        why = "" if stat.S_ISDIR(info.st_mode) else " (ftcal never reads from pipes or devices)"
        raise FtcalError(f"{path}: is {kind_of(info.st_mode)}, not a regular file; give the {what} itself{why}.")
    if max_bytes is not None and info.st_size > max_bytes:
        raise FtcalError(f"{path}: {info.st_size:,} bytes is too large for a {what} (limit {max_bytes:,} bytes).")
    return path


def check_folder_files(folder: str | os.PathLike, what: str = "file") -> None:
    """Refuse a directory whose entries include a FIFO, device or socket (checked before a reader lists it)."""
    try:
        entries = list(os.scandir(folder))
    except OSError as exc:
        raise FtcalError(f"{folder}: cannot list the folder ({exc.strerror or exc}).") from None
    for entry in entries:
        try:
            mode = entry.stat().st_mode
        except OSError:
            continue  # a dangling link: the reader reports it if it needs it
        if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
            raise FtcalError(f"{entry.path}: is {kind_of(mode)}, not a regular {what}; "
                             "ftcal never reads from pipes or devices.")
