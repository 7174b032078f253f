"""Reading CSV files the same way for every file format of the project (measurement files, position reports)."""

from __future__ import annotations

import csv
import gzip
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


def read_csv(path, expected: str, hint: str) -> tuple[int, list[str], list[tuple[int, list[str]]]]:
    """``(header line, header cells, [(line, cells), …])`` of the non-blank records of the CSV file ``path``: read
    (``.gz`` through gzip) as UTF-8, a leading byte-order mark stripped, separated by ``,`` or — when the header line
    has no comma but a semicolon — ``;``, cells stripped of spaces.  UTF-16, zip archives, other encodings, NUL bytes
    (naming the byte), malformed CSV (naming the line) and an empty file are a ValueError naming the file;
    ``expected`` (what the file should be, for :func:`checked_path`) and ``hint`` (what a valid file looks like) go
    into the errors."""
    path = checked_path(path, expected)
    data = path.read_bytes()
    if path.suffix.lower() == ".gz":
        try:
            data = gzip.decompress(data)
        except (OSError, EOFError) as error:
            raise ValueError(f"{path}: not a readable gzip file ({error})") from None
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
    first_line = next((line for line in text.splitlines() if line.strip()), "")
    delimiter = ";" if "," not in first_line and ";" in first_line else ","
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=delimiter)
    records = []
    try:
        start = 1
        for row in reader:
            if any(cell.strip() for cell in row):
                records.append((start, [cell.strip() for cell in row]))
            start = reader.line_num + 1
    except csv.Error as error:
        raise ValueError(f"{path}:{reader.line_num}: malformed CSV ({error})") from None
    if not records:
        raise ValueError(f"{path}: empty file; {hint}")
    return *records[0], records[1:]
