"""Atomic writes: a file appears complete or not at all (temp file in the same folder, then rename). An OSError
(disk full, read-only folder, a missing folder) becomes an :class:`~magsoro.errors.OutputError` naming the file."""

from __future__ import annotations

import functools
import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np

from magsoro.errors import output_error


@functools.cache
def _file_mode() -> int:
    """The mode a file made by open() would get (0666 less the umask): mkstemp's temp files are 0600, and the
    renamed result should be readable as every other output is. The umask is read once (Linux: from
    /proc/self/status, without setting it; elsewhere set and restored)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return 0o666 & ~int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask


def atomic_write_bytes(path, data: bytes) -> None:
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:
        raise output_error(path, exc) from None
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, _file_mode())
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise output_error(path, exc) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_text(path, text: str) -> None:
    atomic_write_bytes(path, text.encode())


def atomic_write_json(path, obj) -> None:
    """Strict JSON (no NaN or Infinity tokens, which JSON does not have): a non-finite number is written as null."""
    atomic_write_text(path, json.dumps(_finite(obj), indent=2, default=_json_default, allow_nan=False) + "\n")


def _finite(o):
    """``o`` with every non-finite float (also inside numpy arrays and scalars) replaced by None."""
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if isinstance(o, dict):
        return {k: _finite(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_finite(v) for v in o]
    if isinstance(o, (np.ndarray, np.generic)):
        return _finite(o.tolist())
    return o


def atomic_save_npz(path, **arrays) -> None:
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp.npz")
        os.close(fd)
    except OSError as exc:
        raise output_error(path, exc) from None
    try:
        np.savez_compressed(tmp, **arrays)
        os.chmod(tmp, _file_mode())
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise output_error(path, exc) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def read_text_file(path, error=None, what: str = "file") -> str:
    """The text of a UTF-8 file (a byte-order mark is allowed). A missing file, a folder, an unreadable file, a
    binary file or another encoding raises ``error`` (a MagsoroError subclass, default MagsoroError) with one
    line naming the file and what is wrong. A relative ``scenes/...`` or ``examples/...`` path that does not exist
    here reads the copy installed with the package (:func:`magsoro.bundled.resolve_data_path`)."""
    from magsoro.bundled import resolve_data_path
    from magsoro.errors import MagsoroError

    error = error or MagsoroError
    path = resolve_data_path(path)
    if not path.exists():
        raise error(f"{path}: {what} not found")
    if path.is_dir():
        raise error(f"{path}: is a folder; a {what} is wanted")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise error(f"{path}: cannot read the {what}: {exc.strerror or exc}") from None
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        raise error(f"{path}: the {what} is UTF-16 text; save it as UTF-8")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        kind = "a binary file" if b"\x00" in data[:4096] else "not UTF-8 text"
        line = data[: exc.start].count(b"\n") + 1
        raise error(f"{path}: the {what} is {kind} (byte 0x{data[exc.start]:02x} on line {line}); "
                    f"save it as UTF-8") from None
    if "\x00" in text:
        raise error(f"{path}: the {what} is a binary file (NUL bytes), not text")
    return text


def read_toml_file(path, error=None, what: str = "file") -> dict:
    """The dict of a TOML file read with :func:`read_text_file`; invalid TOML, or nesting too deep for the
    parser, raises ``error`` naming the file."""
    import tomllib

    from magsoro.errors import MagsoroError

    error = error or MagsoroError
    text = read_text_file(path, error, what)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path}: not valid TOML: {exc}") from None
    except RecursionError:
        raise error(f"{path}: arrays or tables nested too deeply to read") from None
