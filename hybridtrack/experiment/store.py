"""A campaign's result folder: a manifest and one NPZ file per finished chunk of runs.

Layout of ``OUT/``::

    manifest.json                  experiment, locator, parameters, seed, requested n
    runs-0000000-0000019.npz       arrays "index" (c,) and one (c, …) array per result name
    runs-0000020-0000039.npz
    …

Every file is written to a temporary name in the same folder, flushed to disk
and renamed over its final name (``os.replace`` is atomic on POSIX), so a
campaign killed at any moment leaves only complete chunk files plus perhaps a
``*.tmp-*`` file, which the next :meth:`ResultStore.open` deletes.  The chunk
files are the record of which runs are done: a resumed campaign computes only
the indices no chunk holds.  One campaign at a time may write to a folder.
"""

from __future__ import annotations

import json
import os
import uuid
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

FORMAT = 1
MANIFEST = "manifest.json"
_CHUNK_GLOB = "runs-*.npz"
_IDENTITY = ("experiment", "parameters", "seed")


class CampaignMismatch(ValueError):
    """The folder holds results of another experiment, other parameters or another seed."""


class CorruptResults(RuntimeError):
    """Chunk files that contradict each other (a run stored twice, names or shapes differing)."""


def _atomic_write(path: Path, write) -> None:
    temporary = path.with_name(f"{path.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}")
    try:
        with open(temporary, "wb") as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def _json_round_trip(value: Any, what: str) -> Any:
    try:
        return json.loads(json.dumps(value, sort_keys=True))
    except (TypeError, ValueError) as error:
        raise ValueError(f"{what} must be JSON-serializable to be recorded in {MANIFEST}: {error}") from error


class ResultStore:
    """Reads and writes the result folder of one campaign."""

    def __init__(self, folder: str | os.PathLike):
        self.folder = Path(folder)

    # -- manifest -----------------------------------------------------------
    @property
    def manifest_path(self) -> Path:
        return self.folder / MANIFEST

    def manifest(self) -> dict | None:
        """The recorded manifest, or ``None`` for a new folder."""
        if not self.manifest_path.exists():
            return None
        return json.loads(self.manifest_path.read_text(encoding="utf-8"))

    def open(self, *, experiment: str, locator: str | None, parameters: Mapping[str, Any], seed: int, n: int) -> None:
        """Create the folder or check that it holds the same campaign; drop leftovers of a killed write.

        Same campaign = same experiment name, parameters and seed; ``n`` may
        differ (a larger n extends the campaign, run i keeping its seed).
        """
        self.folder.mkdir(parents=True, exist_ok=True)
        for leftover in self.folder.glob("*.tmp-*"):
            leftover.unlink(missing_ok=True)
        wanted = {
            "format": FORMAT,
            "experiment": experiment,
            "locator": locator,
            "parameters": _json_round_trip(dict(parameters), "experiment parameters"),
            "seed": int(seed),
            "n": int(n),
        }
        recorded = self.manifest()
        if recorded is not None:
            differences = [key for key in _IDENTITY if recorded.get(key) != wanted[key]]
            if recorded.get("format") != FORMAT:
                differences.insert(0, "format")
            if differences:
                details = "; ".join(f"{key}: folder has {recorded.get(key)!r}, asked {wanted[key]!r}" for key in differences)
                raise CampaignMismatch(f"{self.folder} holds another campaign ({details}); choose another --out folder")
            if recorded.get("n") == wanted["n"] and recorded.get("locator") == locator:
                return
        text = json.dumps(wanted, indent=2, sort_keys=True) + "\n"
        _atomic_write(self.manifest_path, lambda handle: handle.write(text.encode("utf-8")))

    # -- chunks -------------------------------------------------------------
    def chunk_files(self) -> list[Path]:
        return sorted(self.folder.glob(_CHUNK_GLOB))

    def completed(self) -> np.ndarray:
        """Sorted indices of the runs stored so far (an index stored twice is an error)."""
        parts = []
        for path in self.chunk_files():
            with np.load(path) as data:
                parts.append(np.asarray(data["index"], dtype=np.int64))
        indices = np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)
        unique, counts = np.unique(indices, return_counts=True)
        if np.any(counts > 1):
            raise CorruptResults(f"{self.folder}: run(s) {unique[counts > 1].tolist()} stored more than once")
        return unique

    def write_chunk(self, indices: Iterable[int], results: Mapping[str, np.ndarray]) -> Path:
        """Store finished runs: ``results[name]`` has one row per index, in the order of ``indices``."""
        indices = np.asarray(list(indices), dtype=np.int64)
        if indices.size == 0:
            raise ValueError("write_chunk: no runs to store")
        if "index" in results:
            raise ValueError("write_chunk: 'index' is reserved for the run indices")
        arrays = {"index": indices}
        for name, values in results.items():
            values = np.asarray(values)
            if values.shape[:1] != indices.shape:
                raise ValueError(f"write_chunk: {name!r} has {values.shape[:1]} rows for {indices.size} runs")
            arrays[name] = values
        path = self.folder / f"runs-{indices.min():07d}-{indices.max():07d}.npz"
        if path.exists():
            raise CorruptResults(f"{path} exists already: runs {indices.tolist()} would be stored twice")
        _atomic_write(path, lambda handle: np.savez(handle, **arrays))
        return path

    def load(self, n: int | None = None) -> dict[str, np.ndarray]:
        """Every stored run (indices below ``n`` when given), sorted by index: name → (runs, …), plus ``index``."""
        columns: dict[str, list[np.ndarray]] = {}
        names: tuple[str, ...] | None = None
        shapes: dict[str, tuple] = {}
        for path in self.chunk_files():
            with np.load(path) as data:
                chunk = {name: data[name] for name in data.files}
            chunk_names = tuple(sorted(chunk))
            if names is None:
                names = chunk_names
            elif chunk_names != names:
                raise CorruptResults(f"{path.name}: result names {chunk_names} differ from {names} in earlier chunks")
            for name, values in chunk.items():
                if shapes.setdefault(name, values.shape[1:]) != values.shape[1:]:
                    raise CorruptResults(f"{path.name}: {name!r} has shape {values.shape[1:]} per run, earlier {shapes[name]}")
                columns.setdefault(name, []).append(values)
        if names is None:
            return {"index": np.zeros(0, dtype=np.int64)}
        merged = {name: np.concatenate(parts) for name, parts in columns.items()}
        order = np.argsort(merged["index"], kind="stable")
        merged = {name: values[order] for name, values in merged.items()}
        index = merged["index"]
        if np.any(np.diff(index) == 0):
            raise CorruptResults(f"{self.folder}: run(s) {np.unique(index[:-1][np.diff(index) == 0]).tolist()} stored more than once")
        if n is not None:
            keep = index < n
            merged = {name: values[keep] for name, values in merged.items()}
        return merged
