"""Shared fixtures: the rerun CLI with a throw-away HOME (it writes analytics files there), fake installed
distributions and a clean default-plugin cache."""

import importlib
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import hybridtrack.core.plugins

RERUN = Path(sys.executable).with_name("rerun")


@pytest.fixture(scope="session")
def rerun_cli(tmp_path_factory):
    """Run ``rerun ARGS…`` with HOME in a temporary folder; returns the CompletedProcess."""
    home = tmp_path_factory.mktemp("rerun-home")

    def run(*args):
        return subprocess.run(
            [str(RERUN), *map(str, args)], capture_output=True, text=True, env={"HOME": str(home), "PATH": "/usr/bin:/bin"}, timeout=120
        )

    return run


@pytest.fixture(scope="session")
def clutter_scenario():
    """``make(straight=15, turn=15, density=0.5, seed=2)`` → (truth, sensor, scans): a straight leg then a right
    turn (r = 5) from x0 = [0, 0, 0, 2] (τ = 0.1, Q = 0.01 I), a position sensor "pos" (R = 0.01 I) and its scans
    with clutter of ``density`` and P_D = 0.9 around the track."""
    import numpy as np

    from hybridtrack.engine.clutter import ClutterModel, region_around, simulate_scans
    from hybridtrack.engine.schedule import Schedule, Segment
    from hybridtrack.engine.simulate import simulate_trajectory
    from hybridtrack_plugins.sensors.position import PositionSensor

    def make(straight=15, turn=15, density=0.5, seed=2):
        schedule = Schedule([Segment("straight", straight), Segment("right_turn", turn, 5.0)])
        truth = simulate_trajectory(schedule, [0.0, 0.0, 0.0, 2.0], 0.1, seed=seed, noise_cov=np.diag([0.01, 0.01]))
        sensor = PositionSensor("pos", ("x", "y"), np.diag([0.01, 0.01]))
        scans = simulate_scans(truth, [sensor], ClutterModel(density, 0.9, region_around(truth.positions, 2.0)), seed=seed)
        return truth, sensor, scans

    return make


@pytest.fixture(scope="session")
def clutter_pipeline():
    """``build(estimator, sensor, scans, **options)`` → a Pipeline of the straight and right-turn (r = 5) bank on the
    clutter ``scans`` of ``sensor`` from the prior N([0, 0, 0, 2], 0.01 I), τ = 0.1; ``options`` (recorder, truth,
    detectors, …) are added or override these."""
    import numpy as np

    from hybridtrack.engine.pipeline import Pipeline

    def build(estimator, sensor, scans, **options):
        settings = {
            "models": ["straight", ("right_turn", {"radius": 5.0})],
            "estimator": estimator,
            "sensors": [sensor],
            "candidates": scans,
            "prior": (np.array([0.0, 0.0, 0.0, 2.0]), np.eye(4) * 0.01),
            "tau": 0.1,
        }
        return Pipeline(**(settings | options))

    return build


class DistributionFactory:
    """Writes installed-looking distributions (``*.dist-info`` + modules) into one folder on ``sys.path``.

    ``importlib.metadata`` finds them exactly like ``pip install`` output, so
    their entry points are real; the folder leaves ``sys.path`` and the modules
    leave ``sys.modules`` when the test ends.
    """

    def __init__(self, root: Path, monkeypatch: pytest.MonkeyPatch):
        self.root = root
        self.modules: set[str] = set()
        root.mkdir(parents=True, exist_ok=True)
        monkeypatch.syspath_prepend(str(root))

    def __call__(
        self,
        name: str,
        entry_points: dict[str, str],
        modules: dict[str, str] | None = None,
        *,
        version: str = "1.0",
        group: str = hybridtrack.core.plugins.ENTRY_POINT_GROUP,
        source_root: Path | None = None,
    ) -> Path:
        """Install distribution ``name`` with ``entry_points`` (entry name → module) in ``group``.

        ``modules`` maps a module name to its source (written next to the
        dist-info); ``source_root`` adds an existing source folder to the path
        instead (a ``.pth``-like editable install of e.g. an example project).
        """
        for module, source in (modules or {}).items():
            (self.root / f"{module}.py").write_text(textwrap.dedent(source))
            self.modules.add(module)
        info = self.root / f"{name.replace('-', '_')}-{version}.dist-info"
        info.mkdir()
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
        lines = [f"[{group}]"] + [f"{entry} = {target}" for entry, target in entry_points.items()]
        (info / "entry_points.txt").write_text("\n".join(lines) + "\n")
        if source_root is not None:
            sys.path.insert(0, str(source_root))
        importlib.invalidate_caches()
        return info

    def cleanup(self, extra_paths: list[str]) -> None:
        roots = tuple([str(self.root)] + extra_paths)
        for module in list(sys.modules):
            where = getattr(sys.modules[module], "__file__", None) or ""
            if module in self.modules or where.startswith(roots):
                del sys.modules[module]
        for path in extra_paths:
            while path in sys.path:
                sys.path.remove(path)
        importlib.invalidate_caches()


@pytest.fixture
def install_distribution(tmp_path, monkeypatch):
    """A :class:`DistributionFactory` on a fresh folder; the default plugins are re-read after the test."""
    before = list(sys.path)
    factory = DistributionFactory(tmp_path / "site", monkeypatch)
    hybridtrack.core.plugins.reset()
    yield factory
    factory.cleanup([p for p in sys.path if p not in before and p != str(factory.root)])
    hybridtrack.core.plugins.reset()


@pytest.fixture
def fresh_default_plugins():
    """Forget the cached default plugins before and after the test (for tests that change the environment)."""
    hybridtrack.core.plugins.reset()
    yield
    hybridtrack.core.plugins.reset()
