"""experiments/fit_halves.py run small (four Solent vessels, their first 40 reports, three optimizer iterations): the JSON layout, two folds
over disjoint halves, what each fit estimates and holds, and the verdict read off the rows."""

import importlib.util
import json
from pathlib import Path

import pytest

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
CONFIGS = ["hand_tuned", "fitted", "fitted_holding_course_speed"]


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    spec = importlib.util.spec_from_file_location("_small_fit_halves", EXPERIMENTS / "fit_halves.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    path = tmp_path_factory.mktemp("fit_halves") / "f.json"
    module.main(["--vessels", "4", "--max-reports", "40", "--max-iterations", "3", "--json", str(path)])
    assert path.with_suffix(".md").read_text().count("\n") == 2 + 2 * len(CONFIGS) * 2
    return json.loads(path.read_text())


@pytest.mark.slow  # ≈ 20 s: four fits over 80 reports each
def test_layout_folds_and_fits(small):
    assert set(small) == {"protocol", "folds", "fitted_at_least_as_good", "command"}
    assert small["protocol"]["halves"] == {"A": {"vessels": 2, "reports": 80}, "B": {"vessels": 2, "reports": 80}}
    assert [(f["fit_half"], f["test_half"]) for f in small["folds"]] == [("A", "B"), ("B", "A")]
    start = small["protocol"]["hand_tuned_values"]
    assert {"sigma", "noise_density", "speed_sigma", "course_sigma", "coordinated_turn.rate_density"} <= set(start)
    for f in small["folds"]:
        assert [(r["config"], r["smooth"]) for r in f["rows"]] == [(c, s) for c in CONFIGS for s in (False, True)]
        everything, holding = f["fits"]["fitted"], f["fits"]["fitted_holding_course_speed"]
        assert set(everything["values"]) == set(start) and everything["held"] == []
        assert set(holding["values"]) == set(start) - {"speed_sigma", "course_sigma"}
        assert holding["held"] == ["speed_sigma", "course_sigma"]
        for fit in (everything, holding):
            assert fit["objects"] == 2 and fit["reports"] == 80 and fit["loglik"] >= fit["start_loglik"]
        rows = {(r["config"], r["smooth"]): r for r in f["rows"]}
        verdict = small["fitted_at_least_as_good"][f"fit_{f['fit_half']}_test_{f['test_half']}"]
        for name in ("fitted", "fitted_holding_course_speed"):
            for smooth, output in ((False, "causal"), (True, "smoothed")):
                better = all(rows[name, smooth][k] >= rows["hand_tuned", smooth][k] for k in ("accuracy", "balanced_accuracy"))
                assert verdict[name][output] is better
