"""Atomic file writes: a reader never sees a half-written result, and a crash loses nothing already written."""

from __future__ import annotations

import io
import json
import os
import tempfile
import warnings
from pathlib import Path


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to a temporary file in the same folder, fsync it, then rename it over ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(fd, 0o666 & ~umask)                 # mkstemp makes 0600; results are for sharing
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def atomic_write_figure(path: str | os.PathLike, fig, **savefig_kwargs) -> None:
    """A matplotlib figure saved whole or not at all: rendered into memory with ``fig.savefig(**savefig_kwargs)``
    (the format from ``path``'s suffix unless given), then written with ``atomic_write_bytes``."""
    savefig_kwargs.setdefault("format", Path(path).suffix.lower().lstrip(".") or "png")
    buf = io.BytesIO()
    fig.savefig(buf, **savefig_kwargs)
    atomic_write_bytes(path, buf.getvalue())


def atomic_write_text(path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path, obj) -> None:
    atomic_write_text(path, json.dumps(obj, indent=2, sort_keys=True, allow_nan=True) + "\n")


def append_line(path: str | os.PathLike, line: str) -> None:
    """Append one newline-terminated line with a single O_APPEND write, then fsync.

    A line is written whole or not at all by one ``write`` call on a local file system, so an
    interrupted run leaves at most one torn final line, which readers detect and skip.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = (line.rstrip("\n") + "\n").encode("utf-8")
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    try:
        os.write(fd, data)
        os.fsync(fd)
    finally:
        os.close(fd)


def read_jsonl(path: str | os.PathLike, what: str, required: frozenset = frozenset()) -> list[dict]:
    """The records of an append-only JSON-lines file; a corrupt line raises ValueError naming it.

    The one exception is a final line without its newline: the torn write of a killed run, which is
    skipped with a warning (``set_aside_torn_line`` moves it away before a resumed run appends).
    """
    path = Path(path)
    if not path.exists():
        return []
    lines = path.read_text(encoding="utf-8").split("\n")
    torn = lines.pop()  # "" when the file ends with a newline
    if torn:
        warnings.warn(f"{path}: ignoring a torn last line (an interrupted write): {torn[:80]!r}", stacklevel=2)
    records = []
    for number, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
            if not isinstance(record, dict) or not required <= set(record):
                raise ValueError(f"missing the keys {', '.join(sorted(required))}")
        except ValueError as e:
            raise ValueError(f"{path}, line {number}: corrupt {what} ({e}); fix or remove that line "
                             "(nothing was changed)") from e
        records.append(record)
    return records


def set_aside_torn_line(path: str | os.PathLike) -> None:
    """Move a torn final line (no newline) to ``<name>.torn`` so that appended lines stay whole."""
    path = Path(path)
    if not path.exists():
        return
    data = path.read_bytes()
    cut = data.rfind(b"\n") + 1
    if cut == len(data):
        return
    append_line(path.with_name(path.name + ".torn"), data[cut:].decode("utf-8", "replace"))
    with open(path, "r+b") as f:
        f.truncate(cut)
        f.flush()
        os.fsync(f.fileno())
