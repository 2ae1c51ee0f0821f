"""Writing output files safely: atomic, readable by others, never over an input.

* :func:`atomic_write_bytes` writes a temporary file beside the target and renames it, so a
  reader never sees half a file and an interrupted write leaves nothing behind. The file
  gets the mode an ordinary ``open()`` would give (``0o666`` minus the umask, so 0644 under
  the usual umask 022): ``mkstemp``'s 0600 would hide outputs from a simulator container
  running under another user id.
* :func:`check_output_dir` refuses an output folder that is the input folder, holds an
  input under an output's name, is not a folder, or cannot be created -- before any work
  is done, so a bad ``-o`` costs nothing and leaves nothing.
* :func:`staged_output` collects a command's outputs in a temporary folder and moves them
  into the output folder only when all of them are written (no partial output).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from ._errors import InputError

__all__ = ["atomic_write_bytes", "check_output_dir", "file_mode", "staged_output"]


def file_mode() -> int:
    """Mode of a new ordinary file under the current umask (``0o666 & ~umask``)."""
    umask = os.umask(0o022)
    os.umask(umask)
    return 0o666 & ~umask


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically with an ordinary file mode; returns the path.

    The parent folder is created if needed. On any error (disk full, interrupt) the
    temporary file is removed and ``path`` is untouched.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, file_mode())
        os.replace(tmp, target)
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError) and exc.filename is None:
            exc.filename = str(target)  # "File too large" alone does not say which file
        raise
    return target


def _resolved(path: Path) -> Path:
    return Path(os.path.realpath(path))


def check_output_dir(
    out: str | os.PathLike,
    *,
    inputs: Iterable[str | os.PathLike] = (),
    input_dirs: Iterable[str | os.PathLike] = (),
    names: Iterable[str] = (),
    option: str = "-o",
) -> Path:
    """Check that ``out`` can take the outputs ``names`` without harming an input.

    Parameters
    ----------
    out
        The output folder (need not exist yet; it is not created here).
    inputs
        Input files: none may be in ``out`` under one of ``names``.
    input_dirs
        Input folders (the run folder): ``out`` may not be one of them.
    names
        File names the command writes into ``out``.
    option
        The option that named ``out``, for the message.

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    InputError
        ``out`` is an input folder, would overwrite an input, is not a folder, or lies
        under a file or a folder that cannot be written.
    """
    out = Path(out)
    real_out = _resolved(out)
    for folder in input_dirs:
        if _resolved(Path(folder)) == real_out:
            msg = (
                f"{out}: the output folder ({option}) is the input folder {folder}; "
                "choose another folder, inputs are never overwritten"
            )
            raise InputError(msg)
    targets = {_resolved(real_out / name): name for name in names}
    for item in inputs:
        real = _resolved(Path(item))
        if real in targets or (real.parent == real_out and real.name in targets.values()):
            msg = (
                f"{out}: the output folder ({option}) holds the input {item}, which "
                f"{targets.get(real, real.name)} would overwrite; choose another folder"
            )
            raise InputError(msg)
    if out.exists() and not out.is_dir():
        msg = f"{out}: the output folder ({option}) exists and is not a folder"
        raise InputError(msg)
    probe = real_out
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        msg = f"{out}: cannot create the output folder ({option}): {probe} is a file"
        raise InputError(msg)
    if not os.access(probe, os.W_OK | os.X_OK):
        msg = f"{out}: cannot write the output folder ({option}): {probe} is not writable"
        raise InputError(msg)
    return out


@contextmanager
def staged_output(out: str | os.PathLike) -> Iterator[Path]:
    """A temporary folder inside ``out`` whose files move into ``out`` when the block ends.

    Everything is written into the staging folder first; only when the block ends
    without an error are its files renamed into ``out`` (a rename needs no disk space, so
    a full disk fails while writing, before any output is replaced). On any error,
    interrupt or SIGTERM the staging folder is removed, and so are the folders this
    created, so a failed command leaves ``out`` exactly as it was.
    """
    out = Path(out)
    created: list[Path] = []
    probe = out
    while not probe.exists():
        created.append(probe)
        probe = probe.parent
    out.mkdir(parents=True, exist_ok=True)
    tmp: Path | None = None
    try:
        tmp = Path(tempfile.mkdtemp(prefix=".roadtwin.", suffix=".tmp", dir=out))
        yield tmp
        busy = sorted(p.name for p in tmp.iterdir() if (out / p.name).is_dir())
        if busy:
            msg = f"{out}: cannot write {', '.join(busy)}: a folder of that name exists"
            raise InputError(msg)
        for item in sorted(tmp.iterdir()):
            item.replace(out / item.name)
    except BaseException:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        for folder in created:  # innermost first
            try:
                folder.rmdir()
            except OSError:
                break
        raise
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
