"""Value types: validation naming the field, read-only array copies, equality with arrays."""

import attrs
import numpy as np
import pytest

from hybridtrack.core.interfaces import LinearTransition
from hybridtrack.core.types import Decision, Gaussian, Measurement
from hybridtrack.engine.schedule import SEED001_TABLE1, Schedule, Segment

NOT_SYMMETRIC = [[1.0, 0.5], [0.0, 1.0]]
NOT_PSD = [[1.0, 2.0], [2.0, 1.0]]


def _transition(**changes):
    arguments = dict(F=np.eye(2), B=np.zeros(2), G=np.ones((2, 1)), Q=[[0.5]])
    arguments.update(changes)
    return LinearTransition(**arguments)


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: Gaussian([[1.0, 2.0]], np.eye(2)), r"mean: expected shape \(\*,\), got \(1, 2\)"),
        (lambda: Gaussian([1.0, 2.0], np.eye(3)), r"cov: expected shape \(2, 2\)"),
        (lambda: Gaussian([1.0, np.nan], np.eye(2)), r"mean: contains NaN or inf at index \(1,\)"),
        (lambda: Gaussian([1.0, 2.0], [[1.0, 0.0], [0.0, np.inf]]), "cov: contains NaN or inf"),
        (lambda: Gaussian([1.0, 2.0], NOT_SYMMETRIC), "cov: covariance is not symmetric"),
        (lambda: Gaussian([1.0, 2.0], NOT_PSD), "cov: covariance is not positive semidefinite"),
        (lambda: Gaussian(["a", "b"], np.eye(2)), "mean: expected a numeric array"),
        (lambda: Measurement("gps", 0, [[1.0, 2.0]]), r"z: expected shape \(\*,\)"),
        (lambda: Measurement("gps", 0, [1.0, np.inf]), "z: contains NaN or inf"),
        (lambda: Measurement("gps", -1, [1.0]), "step"),
        (lambda: Segment("left", 0), "steps: expected a positive integer, got 0"),
        (lambda: Segment("left", 2.5), "steps: expected a positive integer, got 2.5"),
        (lambda: Segment("left", True), "steps: expected a positive integer"),
        (lambda: Segment("left", 5, -3.0), "radius: expected a positive finite number"),
        (lambda: Segment("left", 5, np.nan), "radius: expected a positive finite number"),
        (lambda: Segment("ca", 5, None, (1.0, 2.0, 3.0)), "acceleration: expected two finite numbers"),
        (lambda: Segment("ca", 5, None, (1.0, np.nan)), "acceleration: expected two finite numbers"),
        (lambda: Segment("", 5), "mode"),
        (lambda: Schedule([]), "segments"),
        (lambda: Schedule.from_rows([("left", 5, 3.0), ("right", 0)]), "schedule row 1: steps"),
        (lambda: _transition(F=np.ones((2, 3))), r"F: expected shape \(2, 2\)"),
        (lambda: _transition(F=[[1.0, np.nan], [0.0, 1.0]]), "F: contains NaN or inf"),
        (lambda: _transition(B=np.zeros(3)), r"B: expected shape \(2,\)"),
        (lambda: _transition(G=np.ones((2, 2))), r"G: expected shape \(2, 1\)"),
        (lambda: _transition(G=np.ones((2, 2)), Q=NOT_SYMMETRIC), "Q: covariance is not symmetric"),
        (lambda: _transition(G=np.ones((2, 2)), Q=NOT_PSD), "Q: covariance is not positive semidefinite"),
        (lambda: _transition(Q=np.ones((1, 1, 1))), r"Q: expected shape \(q, q\)"),
    ],
)
def test_invalid_values_raise_naming_the_field(build, message):
    with pytest.raises(ValueError, match=message):
        build()


def test_schedule_rows_must_be_segments():
    with pytest.raises(TypeError, match="segments: row 0 is a tuple, expected Segment"):
        Schedule([("left", 5, 3.0)])


def test_arrays_are_read_only_copies():
    mean, cov = np.array([1.0, 2.0]), np.eye(2)
    g = Gaussian(mean, cov)
    mean[0] = 99.0
    cov[0, 0] = 99.0
    assert g.mean[0] == 1.0 and g.cov[0, 0] == 1.0
    assert g.mean.dtype == np.float64 and not g.mean.flags.writeable and not g.cov.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        g.mean[0] = 5.0
    t = _transition()
    assert not any(a.flags.writeable for a in (t.F, t.B, t.G, t.Q))
    m = Measurement("gps", 3, [1, 2])
    assert m.z.dtype == np.float64 and not m.z.flags.writeable
    with pytest.raises(attrs.exceptions.FrozenInstanceError):
        g.mean = np.zeros(2)


def test_equality_compares_arrays():
    g = Gaussian([1, 2], np.eye(2))
    assert g == Gaussian(np.array([1.0, 2.0]), np.eye(2))
    assert g != Gaussian([1.0, 2.5], np.eye(2))
    assert g != Gaussian([1.0, 2.0, 3.0], np.eye(3))
    assert hash(g) == hash(Gaussian([1.0, 2.0], np.eye(2)))
    assert Measurement("gps", 1, [1.0]) == Measurement("gps", 1, [1.0])
    assert Measurement("gps", 1, [1.0]) != Measurement("radar", 1, [1.0])
    assert _transition() == _transition() and _transition() != _transition(B=[0.0, 1.0])
    assert Decision(4, "sprt", "left", 2) == Decision(4, "sprt", "left", 2.0)


def test_linear_transition_maths():
    t = LinearTransition([[1.0, 2.0], [0.0, 1.0]], [1.0, 0.0], [[0.5], [1.0]], [[4.0]])
    np.testing.assert_allclose(t.process_noise, [[1.0, 2.0], [2.0, 4.0]])
    x = np.array([[1.0, 1.0], [0.0, 2.0], [3.0, -1.0]])
    np.testing.assert_allclose(t.apply(x), [[4.0, 1.0], [5.0, 2.0], [2.0, -1.0]])
    assert t.apply(np.zeros((2, 3, 2))).shape == (2, 3, 2)


def test_the_seed001_table_names_registered_motion_models():
    from hybridtrack.core.plugins import get_registry

    known = get_registry().names("motion_model")
    assert {segment.mode for segment in SEED001_TABLE1.segments} <= set(known)


def test_schedule_helpers(tmp_path):
    assert SEED001_TABLE1.total_steps == 360
    assert SEED001_TABLE1.switch_steps() == [0, 50, 125, 175, 250, 300]
    assert (SEED001_TABLE1.segments[1].steps, SEED001_TABLE1.segments[1].radius) == (75, 5.0)
    assert SEED001_TABLE1.segments[1].parameters() == {"radius": 5.0}
    assert SEED001_TABLE1.segments[2].parameters() == {}
    path = tmp_path / "schedule.toml"
    path.write_text(
        '[[segment]]\nmode = "left"\nsteps = 50\nradius = 3.0\n\n'
        '[[segment]]\nmode = "constant_acceleration"\nsteps = 10\nacceleration = [0.5, -0.5]\n'
    )
    schedule = Schedule.from_toml(path)
    assert schedule == Schedule.from_rows([("left", 50, 3.0), {"mode": "constant_acceleration", "steps": 10, "acceleration": [0.5, -0.5]}])
    assert schedule.segments[1].acceleration == (0.5, -0.5)
    (tmp_path / "empty.toml").write_text("title = 'nothing'\n")
    with pytest.raises(ValueError, match="no \\[\\[segment\\]\\] tables"):
        Schedule.from_toml(tmp_path / "empty.toml")
