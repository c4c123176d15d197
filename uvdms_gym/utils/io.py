"""The project's one JSON writer, numpy-to-JSON conversion, file mirroring and C-output silencing (one home each).

:func:`mirror_file` copies a record file (a run's learning curve, its ``meta.json``) into another folder and removes
a stale copy there when the source has none.

Decisions [D], taken once here for every writer:

* NaN and infinities: :func:`to_jsonable` turns non-finite floats into ``None`` (JSON ``null``); the writer
  itself refuses them (``allow_nan=False``), so a file never holds the non-standard ``NaN`` token and a caller
  that forgot the conversion gets a ``ValueError`` instead of an unreadable file.
* Atomicity and durability: the text goes to a temporary file in the target's folder (``tempfile.mkstemp``),
  is flushed and ``fsync``-ed, given the permissions an ordinary ``open`` would give (``0o666 & ~umask``),
  then renamed over the target with ``os.replace``. A reader sees the old file or the new one, never a
  truncated one, even after a crash (the cost is one fsync per file, well below an episode's).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import sys
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any, TextIO

import numpy as np


def to_jsonable(value: Any) -> Any:
    """A plain JSON value: arrays to lists, numpy scalars to Python, non-finite floats to ``None``.

    Mappings become dicts with ``str`` keys, tuples become lists; other values are returned unchanged.
    """
    if isinstance(value, Mapping):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        value = float(value)
        return value if math.isfinite(value) else None
    return value


def _umask() -> int:
    """The process's file-creation mask (read without changing it for longer than two calls)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_json_atomic(path: str | Path, data: Any, *, indent: int | None = 2) -> Path:
    """Write ``data`` as JSON to ``path`` atomically and durably (see the module docstring).

    Args:
        path: The target file; missing parent folders are created.
        data: A JSON value (convert numpy values and NaN first with :func:`to_jsonable`).
        indent: Indentation (``2``: readable, with a final newline); ``None`` writes compact JSON.

    Returns:
        ``path`` as a :class:`~pathlib.Path`.

    Raises:
        ValueError: ``data`` holds NaN or an infinity.
        TypeError: ``data`` holds a value JSON cannot represent.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if indent is None:
        text = json.dumps(data, allow_nan=False, separators=(",", ":"))
    else:
        text = json.dumps(data, allow_nan=False, indent=indent) + "\n"
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; give the file the usual permissions
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def mirror_file(found: str | Path | None, target: str | Path) -> Path | None:
    """Make ``target`` a copy of the file ``found`` (``None`` or missing: remove a stale ``target``).

    Returns:
        ``target``, or ``None`` when there was nothing to copy. A ``found`` that is ``target`` itself is kept.
    """
    target = Path(target)
    if found is None or not Path(found).is_file():
        if target.is_file():
            target.unlink()
        return None
    if Path(found).resolve() != target.resolve():
        shutil.copy2(found, target)
    return target


@contextlib.contextmanager
def quiet_c_stream(stream: TextIO | None = None) -> Iterator[None]:
    """Silence a C-level output stream (its file descriptor) for the duration of the block.

    PyBullet prints from C (its build time on import, ``argv[0]=`` on connect, solver changes), which Python's
    ``contextlib.redirect_stdout`` cannot catch.

    Args:
        stream: ``sys.stdout`` (default) or ``sys.stderr``; one without a real file descriptor is left alone.
    """
    stream = sys.stdout if stream is None else stream
    try:
        stream.flush()
        fd = stream.fileno()
        saved = os.dup(fd)
    except (AttributeError, OSError, ValueError):  # no real stream (e.g. redirected to a non-file)
        yield
        return
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), fd)
            try:
                yield
            finally:
                os.dup2(saved, fd)
    finally:
        os.close(saved)
