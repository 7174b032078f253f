"""run_batch of the adaptive algorithms apart from its equivalence with the runs alone (that is
tests/engine/test_batch.py): inputs named in errors, the requested runs recorded as the run alone records,
batch_margins with ties, and the scripts that batch them (the seed001 experiment runner, the campaign benchmark)."""

import numpy as np
import pytest

from hybridtrack import Gaussian, Schedule
from hybridtrack.algorithms.known_switch import KnownSwitchAdaptive
from hybridtrack.algorithms.unknown_change import UnknownChangeAdaptive
from hybridtrack.engine.simulate import simulate
from hybridtrack_plugins.detectors.sprt_pairwise import batch_margins
from hybridtrack_plugins.sensors.position import PositionSensor

X0 = np.array([0.0, 0.0, 0.0, 2.0])
NOISE = np.diag([0.01, 0.01])
MODES = ["straight", ("right_turn", {"radius": 5.0}), ("left_turn", {"radius": 5.0})]
TOL = dict(rtol=0, atol=1e-12)


def batch_data(schedule, runs):
    """Per-run measurements (runs, K+1, 2) sampled every 0.1 s, run r drawn from seed r."""
    sensor = PositionSensor(noise_cov=NOISE)
    return sensor, np.stack([simulate(schedule, X0, 0.1, [sensor], seed=r)[1][sensor.name] for r in range(runs)])


def test_batch_margins_equal_margins_row_by_row_with_ties():
    rng = np.random.default_rng(3)
    L = np.round(rng.normal(size=(50, 5)), 1)  # ties
    active = rng.random((50, 5)) < 0.6
    expected = np.concatenate([batch_margins(L[i : i + 1], active[i : i + 1]) for i in range(50)])
    np.testing.assert_array_equal(batch_margins(L, active), expected)


class ListRecorder:
    """Keeps every logging call (name, arguments) so two recordings can be compared."""

    def __init__(self):
        self.calls = []

    def log_result(self, result, **context):
        from hybridtrack.recording.results import log_result

        log_result(result, self, **context)

    def __getattr__(self, name):
        if not name.startswith("log_"):
            raise AttributeError(name)
        return lambda *args, **kwargs: self.calls.append((name, args, kwargs))


def same_calls(a, b):
    assert len(a.calls) == len(b.calls)
    for (na, aa, ka), (nb, ab, kb) in zip(a.calls, b.calls):
        assert na == nb and ka.keys() == kb.keys() and len(aa) == len(ab)
        for x, y in zip(list(aa) + list(ka.values()), list(ab) + list(kb.values())):
            if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
                np.testing.assert_allclose(np.asarray(x, float), np.asarray(y, float), **TOL)
            elif isinstance(x, str) and x.startswith("sprt"):
                assert x.split("margin")[0] == y.split("margin")[0]
            else:
                assert x == pytest.approx(y, rel=0, abs=1e-12) if isinstance(x, float) else x == y


def test_batch_records_the_requested_runs_like_the_single_run():
    schedule = Schedule.from_rows([("straight", 8), ("right_turn", 12, 5.0)])
    sensor, z = batch_data(schedule, runs=3)
    adaptive = UnknownChangeAdaptive(modes=MODES, sensors=[sensor], tau=0.1, alpha=0.1, beta=0.1)
    batched, single = ListRecorder(), ListRecorder()
    adaptive.run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), recorders={1: batched})
    adaptive.run({sensor.name: z[1]}, Gaussian(X0, np.eye(4)), recorder=single)
    assert batched.calls and any(c[0] == "log_scalars" for c in batched.calls)
    same_calls(batched, single)
    known = KnownSwitchAdaptive(sensors=[sensor], tau=0.1, n=3, r_min=2.0, r_max=5.0, noise_cov=NOISE)
    batched, single = ListRecorder(), ListRecorder()
    known.run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), schedule, recorders={2: batched})
    known.run({sensor.name: z[2]}, Gaussian(X0, np.eye(4)), schedule, recorder=single)
    same_calls(batched, single)
    joint = KnownSwitchAdaptive(sensors=[sensor], tau=0.1, n=3, r_min=2.0, r_max=5.0, noise_cov=NOISE, switch_estimate="joint")
    batched, single = ListRecorder(), ListRecorder()
    joint.run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), schedule, recorders={0: batched})
    joint.run({sensor.name: z[0]}, Gaussian(X0, np.eye(4)), schedule, recorder=single)
    assert any(c[1][0].startswith("world/estimate/known_switch/hypotheses/") for c in batched.calls if c[0] == "log_path")
    same_calls(batched, single)


def test_batch_input_errors():
    schedule = Schedule.from_rows([("straight", 5)])
    sensor, z = batch_data(schedule, runs=2)
    adaptive = KnownSwitchAdaptive(sensors=[sensor], tau=0.1, n=2, r_min=2.0, r_max=4.0)
    with pytest.raises(ValueError, match="measurements"):
        adaptive.run_batch({sensor.name: z[0]}, Gaussian(X0, np.eye(4)), schedule)
    with pytest.raises(ValueError, match="times"):
        adaptive.run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), schedule, times=np.zeros((3, 6)))
    with pytest.raises(ValueError, match="prior"):
        adaptive.run_batch({sensor.name: z}, (np.zeros((3, 4)), np.eye(4)), schedule)
    with pytest.raises(ValueError, match="recorders"):
        adaptive.run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), schedule, recorders={5: None})


def test_seed001_experiment_batch_equals_the_runner(tmp_path):
    """experiments/seed001_adaptive.py: the batched arrays equal run_one's (small schedule, default and seed rule)."""
    import importlib.util
    from pathlib import Path

    from hybridtrack.apps.experiment.worker import run_seed

    path = Path(__file__).resolve().parents[2] / "experiments" / "seed001_adaptive.py"
    spec = importlib.util.spec_from_file_location("_seed001_batch_test", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for rule in (module.DEFAULT_RULE, module.SEED_RULE):
        parameters = module.EXPERIMENT.with_parameters(R=0.1, steps_scale=0.2, **rule)
        batched = module.batch_arrays(parameters, 3, 1)
        for i in range(3):
            row = module.run_one(i, np.random.default_rng(run_seed(1, i)), **parameters)
            for name, value in row.items():
                np.testing.assert_allclose(batched[name][i], value, **TOL, err_msg=name)


def test_campaign_benchmark_runs_small(tmp_path):
    """benchmarks/campaign.py at a tiny size: the agreed JSON layout (batched and per-run results checked equal inside)."""
    import importlib.util
    import json
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "benchmarks" / "campaign.py"
    spec = importlib.util.spec_from_file_location("_campaign_bench_test", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = tmp_path / "bench.json"
    module.main(["--json", str(out), "--runs", "2", "--steps-scale", "0.1", "--example1-runs", "2", "--clutter-runs", "0"])
    written = json.loads(out.read_text())
    assert set(written) == {"cases"} and len(written["cases"]) == 2
    for case in written["cases"]:
        assert set(case) == {"name", "batched_s", "per_run_s", "speedup"}
        assert case["batched_s"] > 0 and case["per_run_s"] > 0 and case["speedup"] == pytest.approx(case["per_run_s"] / case["batched_s"])
