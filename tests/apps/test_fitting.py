"""``hybridtrack fit`` (hybridtrack.apps.fitting): on simulated tracks with known noise the maximum-likelihood fit
recovers σ and q within two standard errors, the fitted file keeps the rest and tracks, and bad inputs are
one-line errors."""

import json

import numpy as np
import pytest

from hybridtrack.apps.fitting import fit_config, write_fitted
from hybridtrack.apps.tracking import load_config, track_file
from hybridtrack.cli import main
from hybridtrack_plugins.motion.linear_modes import Straight

SIGMA, Q = 8.0, 0.05
CONFIG = """# a comment the fit keeps
[reader]
time = "t"
x = "east"
y = "north"
id = "name"
min_reports = 5

[measurement]
sigma = 20.0

[prior]
position_sigma = 50.0
velocity_sigma = 5.0

[estimator]
algorithm = "imm"
process_noise = 0.3
modes = ["straight"]
"""


def constant_velocity(x, rng, reports):
    """(t, x) at each of ``reports`` fixes 2–8 s apart of a constant-velocity track from x, driven by white
    acceleration of density Q (what the caller draws from ``rng`` between two fixes comes before the next step's)."""
    t = 0.0
    for _ in range(reports):
        yield t, x
        dt = rng.uniform(2.0, 8.0)
        T = Straight(noise_density=Q).transition(dt)
        x = T.F @ x + rng.multivariate_normal(np.zeros(4), T.process_noise)
        t += dt


def write_tracks(path, objects=4, reports=150, seed=3):
    """Constant-velocity tracks (:func:`constant_velocity`), fixes with σ = SIGMA."""
    rng = np.random.default_rng(seed)
    rows = ["t,name,east,north"]
    for o in range(objects):
        for t, x in constant_velocity(np.array([1e5 * o, rng.uniform(-8, 8), 2e5, rng.uniform(-8, 8)]), rng, reports):
            z = x[[0, 2]] + rng.normal(0.0, SIGMA, 2)
            rows.append(f"{t:.3f},o{o},{z[0]:.4f},{z[1]:.4f}")
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.mark.slow  # ≈ 15 s: a few dozen likelihood evaluations over 600 reports
def test_the_fit_recovers_the_simulated_noise(tmp_path):
    csv, cfg = write_tracks(tmp_path / "t.csv"), tmp_path / "c.toml"
    cfg.write_text(CONFIG)
    result = fit_config(csv, cfg)
    assert set(result.values) == {"sigma", "noise_density"}  # one mode: no sojourn to fit
    for name, truth in (("sigma", SIGMA), ("noise_density", Q)):
        value, se = result.values[name], result.standard_errors[name]
        assert np.isfinite(se) and 0 < se < 0.5 * value, (name, value, se)
        assert abs(value - truth) < 2 * se, (name, value, se, truth)
    assert result.loglik > result.start_loglik and result.objects == 4 and result.reports == 600
    tuned = write_fitted(cfg, result.values, tmp_path / "tuned.toml")
    text = tuned.read_text()
    assert text.startswith("# a comment the fit keeps") and "process_noise" not in text
    checked = load_config(tuned)
    assert checked["measurement"]["sigma"] == pytest.approx(result.values["sigma"], rel=1e-5)
    assert checked["estimator"]["noise_density"] == pytest.approx(result.values["noise_density"], rel=1e-5)
    given = load_config(cfg)  # the reader's default jump tolerance follows σ (5 σ): the rest of the reader is as given
    assert checked["reader"] | {"jump_tolerance": 0} == given["reader"] | {"jump_tolerance": 0} and checked["prior"] == given["prior"]
    summary = track_file(csv, tuned, tmp_path / "out")
    assert [o["id"] for o in summary["objects"]] == ["o0", "o1", "o2", "o3"]


def test_the_command_prints_and_writes(tmp_path, capsys):
    csv, cfg = write_tracks(tmp_path / "t.csv", objects=2, reports=40), tmp_path / "c.toml"
    cfg.write_text(CONFIG.replace('modes = ["straight"]', 'modes = ["straight", "left_turn"]\nradii = [300.0]\nsojourn = 60.0'))
    assert main(["fit", str(csv), "--config", str(cfg), "--out", str(tmp_path / "tuned.toml"), "--json"]) == 0
    fit = json.loads(capsys.readouterr().out)
    per_mode = ["sojourn.straight", "sojourn.left_turn"]  # the mean time in each mode
    assert set(fit["values"]) == {"sigma", "noise_density", *per_mode} and fit["objects"] == 2 and fit["reports"] == 80
    tuned = load_config(tmp_path / "tuned.toml")["estimator"]["sojourn"]
    assert tuned == pytest.approx([fit["values"][name] for name in per_mode], rel=1e-5)


def test_held_parameters_keep_the_configurations_values(tmp_path, capsys):
    """``--hold``: the named parameters are neither fitted nor printed, and the tuned file keeps their values."""
    csv, cfg = write_tracks(tmp_path / "t.csv", objects=2, reports=40), tmp_path / "c.toml"
    cfg.write_text(CONFIG)
    argv = ["fit", str(csv), "--config", str(cfg), "--out", str(tmp_path / "tuned.toml"), "--hold", "sigma", "--json"]
    assert main(argv) == 0
    fit = json.loads(capsys.readouterr().out)
    assert set(fit["values"]) == {"noise_density"}
    tuned = load_config(tmp_path / "tuned.toml")
    assert tuned["measurement"]["sigma"] == 20.0 and tuned["estimator"]["noise_density"] == pytest.approx(
        fit["values"]["noise_density"], rel=1e-5
    )


def test_a_fit_stopped_at_its_iteration_limit_says_so(tmp_path, capsys):
    """``--max-iterations 1``: the optimizer stops before a minimum; the fit says it has not converged (JSON and
    text), and the values are where it stopped (the likelihood no worse than at the start)."""
    csv, cfg = write_tracks(tmp_path / "t.csv", objects=2, reports=40), tmp_path / "c.toml"
    cfg.write_text(CONFIG)
    out = ["--out", str(tmp_path / "tuned.toml")]
    assert main(["fit", str(csv), "--config", str(cfg), *out, "--max-iterations", "1", "--json"]) == 0
    fit = json.loads(capsys.readouterr().out)
    assert fit["converged"] is False and fit["loglik"] >= fit["start_loglik"]
    assert main(["fit", str(csv), "--config", str(cfg), *out, "--max-iterations", "1"]) == 0
    assert "not converged: the optimizer stopped at its iteration limit" in capsys.readouterr().out
    assert fit_config(csv, cfg).converged is True
    with pytest.raises(ValueError, match="max_iterations: expected a positive whole number of optimizer iterations, got 0"):
        fit_config(csv, cfg, max_iterations=0)


@pytest.mark.parametrize(
    ("edit", "argv_extra", "message"),
    [
        (lambda c: c.replace('algorithm = "imm"', 'algorithm = "unknown_change"'), [], "fit needs a multiple-model algorithm"),
        (lambda c: c.replace("min_reports = 5", "min_reports = 500"), [], "no object with at least min_reports = 500"),
        (lambda c: c, ["--max-objects", "0"], "--max-objects 0"),
        (lambda c: c, ["--hold", "speed_sigma"], "hold 'speed_sigma': not a parameter of this configuration; expected some of sigma,"),
        (lambda c: c, ["--hold", "sigma", "--hold", "noise_density"], "every parameter held, nothing left to fit"),
        (lambda c: c, ["--max-iterations", "0"], "--max-iterations 0: expected a positive number of iterations"),
    ],
)
def test_bad_inputs_are_one_line_and_status_2(tmp_path, capsys, edit, argv_extra, message):
    csv, cfg = write_tracks(tmp_path / "t.csv", objects=1, reports=20), tmp_path / "c.toml"
    cfg.write_text(edit(CONFIG))
    status = main(["fit", str(csv), "--config", str(cfg), "--out", str(tmp_path / "tuned.toml")] + argv_extra)
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and message in err, err


RATE_DENSITY = 4e-6  # rad²/s³: the turn rate's random walk


def write_turning_tracks(path, objects=4, reports=150, seed=5):
    """Coordinated-turn tracks (ω in the state, a random walk of density RATE_DENSITY; white acceleration Q), fixes
    2–8 s apart with σ = SIGMA."""
    from hybridtrack_plugins.motion.real_motion import CoordinatedTurn

    model, rng, rows = CoordinatedTurn(noise_density=Q, rate_density=RATE_DENSITY), np.random.default_rng(seed), ["t,name,east,north"]
    for o in range(objects):
        x, t = np.array([1e5 * o, 6.0, 2e5, rng.uniform(-6, 6), 0.0]), 0.0
        for _ in range(reports):
            z = x[[0, 2]] + rng.normal(0.0, SIGMA, 2)
            rows.append(f"{t:.3f},o{o},{z[0]:.4f},{z[1]:.4f}")
            dt = rng.uniform(2.0, 8.0)
            noise = rng.multivariate_normal(np.zeros(5), model.transition(dt, x).process_noise)
            x = model.propagate(x, dt) + noise
            t += dt
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.mark.slow  # ≈ 30 s: three parameters over 600 reports
def test_the_fit_recovers_a_modes_own_density(tmp_path):
    """A mode's own density (the coordinated turn's rate_density) is fitted beside σ and q, and written into the
    mode's table of the tuned file."""
    csv, cfg = write_turning_tracks(tmp_path / "t.csv"), tmp_path / "c.toml"
    cfg.write_text(
        CONFIG.replace('modes = ["straight"]', 'modes = [\n    {name = "coordinated_turn", rate_density = 1e-5},  # a comment\n]')
    )
    result = fit_config(csv, cfg)
    assert set(result.values) == {"sigma", "noise_density", "coordinated_turn.rate_density"}
    for name, truth in (("sigma", SIGMA), ("noise_density", Q), ("coordinated_turn.rate_density", RATE_DENSITY)):
        value, se = result.values[name], result.standard_errors[name]
        assert np.isfinite(se) and 0 < se < value, (name, value, se)
        assert abs(value - truth) < 2 * se, (name, value, se, truth)
    checked = load_config(write_fitted(cfg, result.values, tmp_path / "tuned.toml"))
    ((name, params),) = checked["estimator"]["modes"]
    assert name == "coordinated_turn" and params["rate_density"] == pytest.approx(result.values["coordinated_turn.rate_density"], rel=1e-5)


def test_the_modes_densities_a_fit_estimates():
    """Every *_density of a mode's factory; noise_density only where the mode's table gives it; repeated names indexed."""
    from hybridtrack.apps.fitting import mode_densities

    base = {"measurement": {"sigma": 5.0}, "estimator": {"algorithm": "imm"}}
    modes = [
        "straight",
        {"name": "coordinated_turn"},
        {"name": "stop", "noise_density": 0.02},
        {"name": "speed_change", "jerk_density": 2e-4},
    ]
    found = mode_densities(load_config(base | {"estimator": base["estimator"] | {"modes": modes}}))
    assert found == {
        "coordinated_turn.rate_density": (1, "rate_density", 1e-6),
        "stop.noise_density": (2, "noise_density", 0.02),
        "speed_change.jerk_density": (3, "jerk_density", 2e-4),
    }
    twice = mode_densities(load_config(base | {"estimator": base["estimator"] | {"modes": ["coordinated_turn", "coordinated_turn"]}}))
    assert list(twice) == ["coordinated_turn[0].rate_density", "coordinated_turn[1].rate_density"]


SPEED_SIGMA, COURSE_SIGMA = 0.3, 3.0  # m/s, degrees: the noise of the reported speed and course


def write_tracks_with_course(path, objects=4, reports=150, seed=1):
    """Constant-velocity tracks with the speed and course over ground reported beside each fix, speeds 5–10 m/s: the
    velocity with the velocity sensor's error, σ_s = SPEED_SIGMA m/s in every direction and σ_χ = COURSE_SIGMA
    degrees across the track (``VelocitySensor.simulate``)."""
    from hybridtrack_plugins.sensors.velocity import VelocitySensor

    sensor = VelocitySensor(speed_sigma=SPEED_SIGMA, course_sigma=np.radians(COURSE_SIGMA))
    rng = np.random.default_rng(seed)
    rows = ["t,name,east,north,sog,cog"]
    for o in range(objects):
        speed, heading = rng.uniform(5.0, 10.0), rng.uniform(0.0, 2 * np.pi)
        start = np.array([1e5 * o, speed * np.sin(heading), 2e5, speed * np.cos(heading)])
        for t, x in constant_velocity(start, rng, reports):
            z = x[[0, 2]] + rng.normal(0.0, SIGMA, 2)
            vx, vy = sensor.simulate(x, ("x", "vx", "y", "vy"), rng)
            sog, cog = np.hypot(vx, vy), np.degrees(np.arctan2(vx, vy))
            rows.append(f"{t:.3f},o{o},{z[0]:.4f},{z[1]:.4f},{sog:.4f},{cog % 360.0:.4f}")
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.mark.slow  # ≈ 30 s: four parameters over 600 reports
def test_the_fit_recovers_the_noise_of_the_reported_course_and_speed(tmp_path):
    """With ``speed_sigma``/``course_sigma`` (the velocity sensor) the fit estimates them beside σ and q, within two
    standard errors of the simulated noise, and writes them into ``[measurement]``."""
    csv, cfg = write_tracks_with_course(tmp_path / "t.csv"), tmp_path / "c.toml"
    text = CONFIG.replace('id = "name"', 'id = "name"\ncourse = "cog"\nspeed = "sog"\nspeed_unit = "m/s"')
    cfg.write_text(text.replace("sigma = 20.0", "sigma = 20.0\nspeed_sigma = 1.0\ncourse_sigma = 1.0"))
    result = fit_config(csv, cfg)
    assert set(result.values) == {"sigma", "noise_density", "speed_sigma", "course_sigma"}
    for name, truth in (("sigma", SIGMA), ("noise_density", Q), ("speed_sigma", SPEED_SIGMA), ("course_sigma", COURSE_SIGMA)):
        value, se = result.values[name], result.standard_errors[name]
        assert np.isfinite(se) and 0 < se < 0.5 * value, (name, value, se)
        assert abs(value - truth) < 2 * se, (name, value, se, truth)
    measured = load_config(write_fitted(cfg, result.values, tmp_path / "tuned.toml"))["measurement"]
    assert measured["speed_sigma"] == pytest.approx(result.values["speed_sigma"], rel=1e-5)
    assert measured["course_sigma"] == pytest.approx(result.values["course_sigma"], rel=1e-5)
