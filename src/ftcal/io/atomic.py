"""Write files atomically: to a temporary file beside the target, then rename.

A failed or interrupted command never leaves a half-written output behind, and
never writes onto one of its inputs: :func:`protected_inputs` names the input
files of a command (the CLI does it for every command), and every write here
refuses a target that is the same file as one of them (same path after
resolving symbolic links, or the same inode: a hard link).
"""

from __future__ import annotations

import os
import signal
import tempfile
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from ..errors import FtcalError

# (st_dev, st_ino) of each protected input file -> the name it was given by
_PROTECTED: dict[tuple[int, int], str] = {}


@contextmanager
def protected_inputs(paths: Iterable[str | os.PathLike]) -> Iterator[None]:
    """Inside the block, no atomic write may replace any of the existing files ``paths``."""
    added = {}
    for path in paths:
        try:
            info = os.stat(path)
        except (OSError, ValueError):
            continue  # not a file (yet): nothing to protect
        identity = (info.st_dev, info.st_ino)
        if os.path.isfile(path) and identity not in _PROTECTED:
            added[identity] = os.fspath(path)
    _PROTECTED.update(added)
    try:
        yield
    finally:
        for identity in added:
            _PROTECTED.pop(identity, None)


def check_not_an_input(target: str | os.PathLike, option: str = "output") -> None:
    """Raise :class:`FtcalError` if ``target`` is the same file as a protected input.

    Parameters
    ----------
    target : the output path (it may not exist yet)
    option : how the user gave it, for the message (e.g. ``-o``)

    Raises
    ------
    FtcalError
        ``target`` resolves to, or is a hard link of, a file in :func:`protected_inputs`.
    """
    try:
        info = os.stat(target)
    except (OSError, ValueError):
        return  # nothing there to overwrite
    given = _PROTECTED.get((info.st_dev, info.st_ino))
    if given is not None:
        same = "" if os.fspath(target) == given else f" (the same file as {given})"
        raise FtcalError(f"{option} {os.fspath(target)}: is also an input of this command{same}; "
                         "choose another output name.")


@contextmanager
def atomic_path(target: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path; on success it is renamed onto ``target``.

    Problems with the destination (a directory in the way, a parent that is a
    file, no permission, a full disk) become one-line :class:`FtcalError`s.
    """
    target = Path(target)
    if target.is_dir():
        raise FtcalError(f"{target}: is a directory; give a file name to write.")
    check_not_an_input(target)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FtcalError(f"{target}: cannot create the output file ({exc.strerror or exc}).") from None
    # Signals wait while the temporary file is created and not yet owned by the clean-up below.
    held = _hold_signals()
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    except OSError as exc:
        _release_signals(held)
        raise FtcalError(f"{target}: cannot create the output file ({exc.strerror or exc}).") from None
    tmp_path = Path(tmp)
    try:
        _release_signals(held)
        os.close(fd)
        # mkstemp makes the file private (0600); outputs get the usual permissions.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        yield tmp_path
        os.replace(tmp_path, target)
    except OSError as exc:
        raise FtcalError(f"{target}: cannot write the output file ({exc.strerror or exc}).") from None
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


_HELD_SIGNALS = {getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)}


def _hold_signals():
    return signal.pthread_sigmask(signal.SIG_BLOCK, _HELD_SIGNALS) if hasattr(signal, "pthread_sigmask") else None


def _release_signals(previous) -> None:
    if previous is not None:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def write_text_atomic(target: str | os.PathLike, text: str, newline: str | None = None) -> None:
    """Write ``text`` to ``target`` atomically (UTF-8)."""
    with atomic_path(target) as tmp:
        with open(tmp, "w", encoding="utf-8", newline=newline) as fh:
            fh.write(text)


def write_with(target: str | os.PathLike, writer: Callable[[Path], None]) -> None:
    """Call ``writer(tmp_path)`` and move the result onto ``target``."""
    with atomic_path(target) as tmp:
        writer(tmp)
