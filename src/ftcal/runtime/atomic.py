"""Write files atomically: to a temporary file beside the target, then rename.

A failed or interrupted command never leaves a half-written output behind, and
never writes onto one of its inputs: :func:`protected_inputs` names the input
files of a command (the CLI does it for every command), and every write here
refuses a target that is the same file as one of them (same path after
resolving symbolic links, or the same inode: a hard link).
"""

from __future__ import annotations

import os
import stat
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path

from .errors import FtcalError, ParameterError

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


def check_not_an_input(target: str | os.PathLike, parameter: str = "output") -> None:
    """Raise :class:`FtcalError` if ``target`` is the same file as a protected input.

    Parameters
    ----------
    target : the output path (it may not exist yet)
    parameter : the parameter that gave it, for the message (the CLI shows its flag, e.g. ``-o``)

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
        raise ParameterError(parameter, f"{{{parameter}}} {os.fspath(target)}: is also an input of this "
                             f"command{same}; choose another output name.")


def output_folder(path: str | os.PathLike, parameter: str = "output") -> Path:
    """A writable folder for a step's files, made if missing.

    Parameters
    ----------
    path : the folder
    parameter : str
        The step's parameter that gave it, named in the error (the CLI shows its flag).

    Returns
    -------
    Path

    Raises
    ------
    ParameterError
        ``path`` is something other than a folder, cannot be made, or is not writable.
    """
    out = Path(path)
    name = "{" + parameter + "}"
    if out.exists() and not out.is_dir():
        raise ParameterError(parameter, f"{name} {out}: exists and is not a folder; give a folder for the files.")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ParameterError(parameter, f"{name} {out}: cannot create the folder ({exc.strerror or exc}).") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise ParameterError(parameter, f"{name} {out}: the folder is not writable.")
    return out


@contextmanager
def _temporary(target: Path) -> Iterator[Path]:
    """Yield a new empty temporary file beside ``target``; it is removed on exit unless renamed away.

    Problems with the destination (a directory in the way, a parent that is a
    file, no permission, a full disk) become one-line :class:`FtcalError`s.
    """
    if target.is_dir():
        raise FtcalError(f"{target}: is a directory; give a file name to write.")
    try:
        mode = os.lstat(target).st_mode  # the name itself: a symbolic link is replaced, never what it points to
    except (OSError, ValueError):
        mode = None
    if mode is not None and not (stat.S_ISREG(mode) or stat.S_ISLNK(mode)):
        from .inputs import kind_of

        # the rename would replace the device node itself (as root, /dev/zero became a CSV file)
        raise FtcalError(f"{target}: is {kind_of(mode)}; give a file name to write (ftcal never replaces devices, "
                         "pipes or sockets).")
    check_not_an_input(target)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        # mkdir says "File exists" when a parent is a file: name that parent instead.
        blocking = next((p for p in target.parents if p.exists() and not p.is_dir()), None)
        why = f"{blocking} is a file, not a directory" if blocking is not None else exc.strerror or exc
        raise FtcalError(f"{target}: cannot create the output file ({why}).") from None
    # The name is chosen before the file exists, so the clean-up below owns the file from
    # the instant it is created: a signal arriving at any point cannot orphan it.
    tmp_path = None
    try:
        try:
            fd = None
            while fd is None:
                tmp_path = target.parent / f".{target.name}.{os.urandom(8).hex()}.tmp"
                try:
                    # Mode 0666 less the umask: outputs get the usual permissions.
                    fd = os.open(tmp_path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
                except FileExistsError:
                    tmp_path = None  # someone else's file: never ours to remove
            os.close(fd)
        except OSError as exc:
            raise FtcalError(f"{target}: cannot create the output file ({exc.strerror or exc}).") from None
        yield tmp_path
    except OSError as exc:
        raise FtcalError(f"{target}: cannot write the output file ({exc.strerror or exc}).") from None
    finally:
        if tmp_path is not None and os.path.lexists(tmp_path):
            tmp_path.unlink()


@contextmanager
def atomic_path(target: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path; on success it is renamed onto ``target``.

    Problems with the destination (a directory in the way, a parent that is a
    file, no permission, a full disk) become one-line :class:`FtcalError`s.
    """
    target = Path(target)
    with _temporary(target) as tmp:
        yield tmp
        os.replace(tmp, target)


@contextmanager
def atomic_paths(targets: Sequence[str | os.PathLike]) -> Iterator[list[Path]]:
    """Yield one temporary path per target; on success all are renamed into place, else none.

    All or nothing for multi-file outputs (a ``.h`` and its ``.c``): if writing
    any part fails, no target changes; if a rename fails after others
    succeeded, those are rolled back (the previous files restored, new ones
    removed).
    """
    targets = [Path(t) for t in targets]
    with ExitStack() as stack:
        temps = [stack.enter_context(_temporary(t)) for t in targets]
        yield temps
        _commit(list(zip(temps, targets)))


def _commit(pairs: list[tuple[Path, Path]]) -> None:
    """Rename every temporary onto its target, undoing the done renames if one fails."""
    done: list[tuple[Path, Path | None]] = []  # (target, backup of its previous content or None)
    try:
        for tmp, target in pairs:
            backup = None
            if os.path.lexists(target):
                backup = target.parent / f".{target.name}.{os.urandom(8).hex()}.old"
                os.link(target, backup)
            done.append((target, backup))
            os.replace(tmp, target)
    except OSError as exc:
        for target, backup in reversed(done):
            try:
                if backup is not None:
                    os.replace(backup, target)
                elif os.path.lexists(target):
                    target.unlink()
            except OSError:
                pass  # best effort: the error below still names the failed output
        raise FtcalError(f"{exc.filename or pairs[-1][1]}: cannot write the output file "
                         f"({exc.strerror or exc}); no output was changed.") from None
    finally:
        for _, backup in done:
            if backup is not None and os.path.lexists(backup):
                backup.unlink()


def write_text_atomic(target: str | os.PathLike, text: str, newline: str | None = None) -> None:
    """Write ``text`` to ``target`` atomically (UTF-8)."""
    write_texts_atomic({target: text}, newline=newline)


def write_texts_atomic(files: Mapping[str | os.PathLike, str], newline: str | None = None) -> None:
    """Write every ``{target: text}`` atomically and all together (UTF-8): all files or none.

    A lone surrogate (text decoded from a broken file) is written as its
    ``\\uXXXX`` escape instead of failing mid-write.
    """
    with atomic_paths(list(files)) as temps:
        for tmp, text in zip(temps, files.values()):
            with open(tmp, "w", encoding="utf-8", errors="backslashreplace", newline=newline) as fh:
                fh.write(text)


def write_with(target: str | os.PathLike, writer: Callable[[Path], None]) -> None:
    """Call ``writer(tmp_path)`` and move the result onto ``target``."""
    with atomic_path(target) as tmp:
        writer(tmp)
