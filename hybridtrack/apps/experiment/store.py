"""A campaign's result folder: a manifest, a lock and one NPZ file per finished chunk of runs.

Layout of ``OUT/``::

    manifest.json                  experiment, locator, parameters, seed, requested n
    .lock                          held (flock) by the campaign writing here; holds its pid
    runs-0000000-0000019.npz       arrays "index" (c,), "__campaign__" and one (c, …) array per result name
    set_aside/                     unusable files moved away by ``set_aside=True`` (``--set-aside``)

Writes are atomic (a ``*.tmp-*`` file renamed; :meth:`ResultStore.open` deletes leftovers), one campaign at a
time (:meth:`ResultStore.locked`); every chunk records its campaign's identity (format, experiment, parameters,
seed) as the JSON text ``__campaign__`` and every file read is checked (:class:`CorruptResults`,
:class:`CampaignMismatch`): docs/experiments.md, "Storage and resumption".
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import uuid
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

try:  # POSIX; elsewhere the folder is not locked
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

FORMAT = 1
MANIFEST = "manifest.json"
#: the reserved chunk array holding the campaign identity as JSON text
IDENTITY_ARRAY = "__campaign__"
_IDENTITY = ("format", "experiment", "parameters", "seed")
_REMEDY = "run again with --set-aside (Python: set_aside=True) to move it to {folder}/set_aside/ and recompute its runs"


class CampaignMismatch(ValueError):
    """The folder (its manifest or a chunk file) holds results of another experiment, other parameters or another seed."""


class CorruptResults(ValueError):
    """An unreadable or inconsistent file in the result folder (empty, truncated, foreign, damaged manifest,
    a run stored twice, names or shapes differing); the message names the file."""


class CampaignLocked(RuntimeError):
    """Another campaign (another process, or another :meth:`ResultStore.locked` here) writes to the folder."""


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


def campaign_identity(experiment: str, parameters: Mapping[str, Any], seed: int) -> dict[str, Any]:
    """What makes two campaigns the same (format, experiment name, parameters, seed); ``n`` and the locator may differ."""
    try:
        parameters = json.loads(json.dumps(dict(parameters), sort_keys=True))
    except (TypeError, ValueError) as error:
        raise ValueError(f"experiment parameters must be JSON-serializable to be recorded in {MANIFEST}: {error}") from error
    return {"format": FORMAT, "experiment": experiment, "parameters": parameters, "seed": int(seed)}


def _differences(recorded: Mapping[str, Any], wanted: Mapping[str, Any]) -> str:
    keys = [key for key in _IDENTITY if recorded.get(key) != wanted.get(key)]
    return "; ".join(f"{key}: folder has {recorded.get(key)!r}, asked {wanted.get(key)!r}" for key in keys)


def _is_integer(value: Any, low: float = -math.inf) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, np.integer)) and value >= low


def _check_manifest(data: Any) -> str | None:
    """What is wrong with a parsed manifest, or ``None``."""
    if not isinstance(data, dict):
        return f"expected a JSON object, got {type(data).__name__}"
    expected = {
        "format": (_is_integer, "an integer"),
        "experiment": (lambda v: isinstance(v, str) and v != "", "a non-empty string"),
        "parameters": (lambda v: isinstance(v, dict), "an object"),
        "seed": (lambda v: _is_integer(v, 0), "a non-negative integer"),
        "n": (lambda v: _is_integer(v, 1), "a positive integer"),
        "locator": (lambda v: v is None or isinstance(v, str), "a string or null"),
    }
    for key, (valid, what) in expected.items():
        if key not in data:
            return f"has no {key!r} entry"
        if not valid(data[key]):
            return f"{key!r} is {data[key]!r}, expected {what}"
    return None


def _chunk_problem(path: Path, arrays: dict[str, np.ndarray]) -> str | None:
    """What is wrong with the arrays of one chunk file, or ``None``."""
    if "index" not in arrays:
        return f"has no 'index' array (holds {sorted(arrays)}); not a chunk written by a campaign"
    index = arrays["index"]
    if index.ndim != 1 or index.dtype.kind not in "iu" or index.size == 0:
        return f"'index' is {index.dtype} with shape {index.shape}, expected a non-empty 1-D integer array"
    if np.any(index < 0):
        return f"'index' holds negative run indices {index[index < 0][:5].tolist()}"
    if len(np.unique(index)) != index.size:
        return "'index' holds a run index twice"
    expected_name = f"runs-{int(index.min()):07d}-{int(index.max()):07d}.npz"
    if path.name != expected_name:
        return f"holds runs {int(index.min())}-{int(index.max())}, so its name should be {expected_name}"
    for name, values in arrays.items():
        if name == IDENTITY_ARRAY:
            if values.shape != () or values.dtype.kind != "U":
                return f"{IDENTITY_ARRAY!r} is {values.dtype} with shape {values.shape}, expected JSON text"
        elif values.dtype.kind not in "biuf":
            return f"result {name!r} has dtype {values.dtype}, expected numbers"
        elif values.shape[:1] != index.shape:
            return f"result {name!r} has {values.shape[:1]} rows for {index.size} runs"
    return None


def read_chunk(path: str | os.PathLike) -> tuple[dict[str, np.ndarray], dict[str, Any] | None]:
    """The result arrays of one chunk file and the campaign identity it records (``None`` for chunks written
    before identities were recorded), checked; :class:`CorruptResults` naming the file and the fault otherwise."""
    path = Path(path)
    try:
        size = path.stat().st_size
        if not path.is_file():
            raise IsADirectoryError(f"{path} is not a file")
    except OSError as error:
        raise CorruptResults(f"chunk file {path} cannot be read ({error})") from error
    if size == 0:
        raise CorruptResults(f"chunk file {path} is empty (0 bytes), expected an NPZ archive")
    try:
        data = np.load(path, allow_pickle=False)
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise ValueError(f"a single {type(data).__name__}, not an NPZ archive")
        with data:
            arrays = {name: data[name] for name in data.files}
    except Exception as error:  # any failure to parse the file is a fault of the file
        reason = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise CorruptResults(
            f"chunk file {path} ({size} bytes) is not a readable NPZ archive (truncated or foreign file: {reason})"
        ) from error
    problem = _chunk_problem(path, arrays)
    if problem is not None:
        raise CorruptResults(f"chunk file {path} {problem}")
    if IDENTITY_ARRAY not in arrays:
        return arrays, None
    try:
        identity = json.loads(str(arrays.pop(IDENTITY_ARRAY)))
    except ValueError as error:
        raise CorruptResults(f"chunk file {path}: {IDENTITY_ARRAY!r} is not valid JSON ({error})") from error
    if not isinstance(identity, dict) or any(key not in identity for key in _IDENTITY):
        raise CorruptResults(f"chunk file {path}: {IDENTITY_ARRAY!r} is {identity!r}, expected format, experiment, parameters, seed")
    return arrays, identity


class ResultStore:
    """Reads and writes the result folder of one campaign.

    After :meth:`open`, the store knows its campaign identity: chunks it
    writes record it and chunks it reads must match it.
    """

    def __init__(self, folder: str | os.PathLike):
        self.folder = Path(folder)
        self.manifest_path = self.folder / MANIFEST
        self.identity: dict[str, Any] | None = None
        self._manifest_present = True
        #: (original path, new path, reason) of every file this store moved into ``set_aside/``
        self.set_aside_files: list[tuple[Path, Path, str]] = []

    @contextlib.contextmanager
    def locked(self) -> Iterator[None]:
        """Hold the folder's exclusive lock (creating the folder); :class:`CampaignLocked` when another campaign holds it."""
        self._make_folder()
        path = self.folder / ".lock"
        descriptor = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            if fcntl is not None:
                try:
                    fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    holder = os.pread(descriptor, 64, 0).decode("ascii", "replace").strip() or "unknown"
                    raise CampaignLocked(
                        f"{self.folder} is in use by another campaign (process {holder} holds {path}); "
                        "wait for it to finish or choose another --out folder"
                    ) from None
            os.ftruncate(descriptor, 0)
            os.pwrite(descriptor, f"{os.getpid()}\n".encode("ascii"), 0)
            try:
                yield
            finally:
                os.ftruncate(descriptor, 0)
        finally:
            os.close(descriptor)  # releases the flock

    def _make_folder(self) -> None:
        if self.folder.exists() and not self.folder.is_dir():
            raise NotADirectoryError(f"result folder {self.folder} is a file, expected a folder (choose another --out)")
        self.folder.mkdir(parents=True, exist_ok=True)

    def manifest(self, set_aside: bool = False) -> dict | None:
        """The recorded manifest, or ``None`` for a new folder; :class:`CorruptResults` naming the file when
        damaged (with ``set_aside``: the file moved to ``set_aside/`` and ``None``)."""
        path = self.manifest_path
        if not path.exists():
            return None
        try:
            text = path.read_text(encoding="utf-8")
            problem = _check_manifest(data := json.loads(text)) if text.strip() else "is empty, expected a JSON object"
        except (OSError, UnicodeDecodeError) as error:
            problem = f"cannot be read ({error})"
        except json.JSONDecodeError as error:
            problem = f"is not valid JSON ({error})"
        if problem is None:
            return data
        if not set_aside:
            remedy = _REMEDY.format(folder=self.folder).replace("recompute its runs", "write a new one")
            raise CorruptResults(f"manifest {path} {problem}; {remedy}")
        self._set_aside(path, f"manifest {problem}")
        return None

    def open(
        self,
        *,
        experiment: str,
        locator: str | None,
        parameters: Mapping[str, Any],
        seed: int,
        n: int,
        set_aside: bool = False,
    ) -> np.ndarray:
        """Create the folder or check that it holds the same campaign; drop leftovers of a killed write.

        Same campaign = same experiment name, parameters and seed, in the
        manifest and in every chunk file; ``n`` may differ (a larger n extends
        the campaign, run i keeping its seed).  A damaged manifest or chunk
        file is an error, or with ``set_aside`` is moved to ``set_aside/``.
        Call it while holding :meth:`locked`.  Returns the sorted indices of
        the runs stored.
        """
        self._make_folder()
        for leftover in self.folder.glob("*.tmp-*"):
            leftover.unlink(missing_ok=True)
        identity = campaign_identity(experiment, parameters, seed)
        wanted = {**identity, "locator": locator, "n": int(n)}
        recorded = self.manifest(set_aside)
        if recorded is not None and (details := _differences(recorded, identity)):
            raise CampaignMismatch(f"{self.folder} holds another campaign ({details}); choose another --out folder")
        self.identity = identity
        self._manifest_present = recorded is not None
        done = self.completed(set_aside=set_aside)
        if recorded is None or recorded.get("n") != wanted["n"] or recorded.get("locator") != locator:
            text = json.dumps(wanted, indent=2, sort_keys=True) + "\n"
            _atomic_write(self.manifest_path, lambda handle: handle.write(text.encode("utf-8")))
        return done

    def _set_aside(self, path: Path, reason: str) -> None:
        """Move ``path`` into ``set_aside/`` (never overwriting) and note why in ``set_aside/REASONS.txt``."""
        folder = self.folder / "set_aside"
        folder.mkdir(exist_ok=True)
        target, copy = folder / path.name, 0
        while target.exists():
            copy += 1
            target = folder / f"{path.name}.{copy}"
        os.replace(path, target)
        with open(folder / "REASONS.txt", "a", encoding="utf-8") as notes:
            notes.write(f"{target.name}: {reason}\n")
        self.set_aside_files.append((path, target, reason))

    def _reference_identity(self) -> tuple[dict[str, Any] | None, bool]:
        """The identity chunks must match (this store's, else the manifest's) and whether a manifest vouches for old chunks."""
        if self.identity is not None:
            return self.identity, self._manifest_present
        recorded = self.manifest() if self.folder.is_dir() else None
        if recorded is None:
            return None, False
        return {key: recorded[key] for key in _IDENTITY}, True

    def _chunks(self, set_aside: bool = False) -> Iterator[tuple[Path, dict[str, np.ndarray]]]:
        """Every usable chunk file with its arrays (identity removed), checked one by one and against each other.

        Result names and shapes must agree between chunks; the layout held by
        most runs is taken as right and a chunk differing from it is the bad
        one.  A bad chunk raises, or with ``set_aside`` is moved away.
        """
        reference, vouched = self._reference_identity()

        def reject(path: Path, error: CorruptResults | CampaignMismatch) -> None:
            if not set_aside:
                raise type(error)(f"{error}; {_REMEDY.format(folder=self.folder)}") from error
            self._set_aside(path, str(error))

        readable: list[tuple[Path, dict[str, np.ndarray], str]] = []
        for path in sorted(self.folder.glob("runs-*.npz")):
            try:
                arrays, identity = read_chunk(path)
                if identity is None and not vouched:
                    raise CorruptResults(
                        f"chunk file {path} records no campaign identity (written by an older version) and "
                        f"{self.manifest_path} is missing, so its seed cannot be checked"
                    )
                if identity is not None:
                    reference = reference or identity
                    if details := _differences(identity, reference):
                        raise CampaignMismatch(f"chunk file {path} belongs to another campaign ({details})")
            except (CorruptResults, CampaignMismatch) as error:
                reject(path, error)
                continue
            layout = "{" + ", ".join(f"{name}: {arrays[name].shape[1:]}" for name in sorted(arrays)) + "}"
            readable.append((path, arrays, layout))

        runs: dict[str, int] = {}
        for _, arrays, layout in readable:
            runs[layout] = runs.get(layout, 0) + arrays["index"].size
        majority = max(runs, key=runs.get, default="")  # ties: the first file's
        owner: dict[int, Path] = {}
        for path, arrays, layout in readable:
            try:
                if layout != majority:
                    first = next(other for other, _, kind in readable if kind == majority)
                    raise CorruptResults(
                        f"chunk file {path}: result names and shapes per run {layout} differ from "
                        f"{majority} in {first.name} and the other chunks"
                    )
                twice = sorted(int(i) for i in arrays["index"] if int(i) in owner)
                if twice:
                    raise CorruptResults(f"{self.folder}: run(s) {twice} stored more than once ({owner[twice[0]].name} and {path.name})")
            except CorruptResults as error:
                reject(path, error)
                continue
            owner.update((int(i), path) for i in arrays["index"])
            yield path, arrays

    def completed(self, set_aside: bool = False) -> np.ndarray:
        """Sorted indices of the runs stored so far; a bad or foreign chunk or a run stored twice is an error
        (or, with ``set_aside``, the offending file is moved to ``set_aside/``)."""
        parts = [arrays["index"].astype(np.int64) for _, arrays in self._chunks(set_aside)]
        return np.sort(np.concatenate(parts)) if parts else np.zeros(0, dtype=np.int64)

    def write_chunk(self, indices: Iterable[int], results: Mapping[str, np.ndarray]) -> Path:
        """Store finished runs: ``results[name]`` has one row per index, in the order of ``indices``."""
        indices = np.asarray(list(indices), dtype=np.int64)
        if indices.size == 0:
            raise ValueError("write_chunk: no runs to store")
        for reserved in ("index", IDENTITY_ARRAY):
            if reserved in results:
                raise ValueError(f"write_chunk: {reserved!r} is reserved (run indices, campaign identity)")
        arrays = {"index": indices}
        for name, values in results.items():
            values = np.asarray(values)
            if values.shape[:1] != indices.shape:
                raise ValueError(f"write_chunk: {name!r} has {values.shape[:1]} rows for {indices.size} runs")
            arrays[name] = values
        identity = self._reference_identity()[0]
        if identity is not None:
            arrays[IDENTITY_ARRAY] = np.array(json.dumps(identity, sort_keys=True))
        path = self.folder / f"runs-{indices.min():07d}-{indices.max():07d}.npz"
        if path.exists():
            raise CorruptResults(f"{path} exists already: runs {indices.tolist()} would be stored twice")
        _atomic_write(path, lambda handle: np.savez(handle, **arrays))
        return path

    def load(self, n: int | None = None) -> dict[str, np.ndarray]:
        """Every stored run (indices below ``n`` when given), sorted by index: name → (runs, …), plus ``index``."""
        chunks = [arrays for _, arrays in self._chunks()]  # all with the same names: _chunks raises otherwise
        if not chunks:
            return {"index": np.zeros(0, dtype=np.int64)}
        merged = {name: np.concatenate([chunk[name] for chunk in chunks]) for name in chunks[0]}
        order = np.argsort(merged["index"], kind="stable")
        if n is not None:
            order = order[merged["index"][order] < n]
        return {name: values[order] for name, values in merged.items()}
