"""Reading CSV text the same way for every file format of the project (measurement files, position reports).

:func:`checked_path` refuses what is not a file name, a directory or a missing file; :func:`decode_csv_text`
accepts UTF-8 (a leading byte-order mark stripped) and refuses UTF-16, zip archives, other encodings and NUL
bytes, naming the file and the offending byte; :func:`csv_records` splits the text into records with their line
numbers, the separator ``,`` or — when the header line has no comma but a semicolon — ``;``, blank records
skipped; :func:`finite_number` reads a plain decimal cell.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from pathlib import Path

#: a plain ASCII decimal number: no ``inf``/``nan`` words, no ``_`` separators
NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?", re.ASCII)


def checked_path(path, expected: str | None = None) -> Path:
    """``path`` as a Path: a TypeError unless it is a str or os.PathLike; with ``expected`` (what the file should
    be), an IsADirectoryError for a directory and a FileNotFoundError for a missing file, naming it."""
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path: expected a file name (str or os.PathLike), got {type(path).__name__} ({path!r})")
    path = Path(path)
    if expected is not None and path.is_dir():
        raise IsADirectoryError(f"{path}: is a directory, expected {expected}")
    if expected is not None and not path.exists():
        raise FileNotFoundError(f"{path}: no such file (expected {expected})")
    return path


def finite_number(cell: str) -> float | None:
    """A finite float, or None for an empty, non-numeric or non-finite cell."""
    if not NUMBER.fullmatch(cell):
        return None
    value = float(cell)
    return value if math.isfinite(value) else None


def decode_csv_text(path: Path, data: bytes, hint: str) -> str:
    """UTF-8 text of ``data`` read from ``path``, a leading byte-order mark stripped; anything else is a ValueError
    naming the file (``hint`` says what a valid file looks like)."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise ValueError(f"{path}: the file is UTF-16 text; save it as UTF-8 ({hint})")
    if data.startswith(b"PK\x03\x04"):
        raise ValueError(f"{path}: the file is a zip archive (an NPZ file?), not a text CSV; name it .npz if it is one")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise ValueError(f"{path}: not a UTF-8 text CSV (byte 0x{data[error.start]:02x} at offset {error.start}); {hint}") from None
    if "\x00" in text:
        raise ValueError(f"{path}: not a UTF-8 text CSV (NUL byte at offset {text.index(chr(0))}); {hint}")
    return text


def csv_records(path: Path, text: str, *, strip: bool = False) -> list[tuple[int, list[str]]]:
    """(line, cells) for each non-blank record (cells stripped of spaces with ``strip``); malformed CSV names the line."""
    first_line = next((line for line in text.splitlines() if line.strip()), "")
    delimiter = ";" if "," not in first_line and ";" in first_line else ","
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=delimiter)
    records = []
    try:
        start = 1
        for row in reader:
            if any(cell.strip() for cell in row):
                records.append((start, [cell.strip() for cell in row] if strip else row))
            start = reader.line_num + 1
    except csv.Error as error:
        raise ValueError(f"{path}:{reader.line_num}: malformed CSV ({error})") from None
    return records
