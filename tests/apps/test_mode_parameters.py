"""``[estimator] modes`` tables pass any parameter of the registered model, a third party's too, and refuse the ones
it does not have with its parameter list (issue 25, item 2)."""

from typing import ClassVar

import attrs
import pytest

from hybridtrack import hookimpl
from hybridtrack.apps.tracking import ConfigError, build_tracker, load_config
from hybridtrack.core.plugins import load_plugins
from hybridtrack_plugins.motion.linear_modes import Straight


@attrs.frozen
class Braking(Straight):
    """A third party's mode with a parameter of its own (here unused by the motion)."""

    rate: float = attrs.field(default=0.1, converter=float)
    name: ClassVar[str] = "braking"


class BrakingPlugin:
    @hookimpl
    def register_motion_models(self, registry):
        registry.add("braking", Braking)


def config(*modes):
    return {"measurement": {"sigma": 10.0}, "estimator": {"algorithm": "imm", "noise_density": 0.001, "modes": list(modes)}}


def test_a_models_own_parameters_reach_it():
    _, _, models = build_tracker(load_config(config("straight", {"name": "coordinated_turn", "max_rate": 0.05, "rate_density": 1e-5})))
    assert models[1].max_rate == 0.05 and models[1].rate_density == 1e-5 and models[1].noise_density == 0.001
    _, _, (turn,) = build_tracker(load_config(config({"name": "left_turn", "radius": 500})))
    assert turn.radius == 500.0


def test_a_third_party_models_parameters_reach_it():
    registry = load_plugins(extra=[BrakingPlugin()]).registry
    cfg = load_config(config("straight", {"name": "braking", "rate": 0.5}), registry)
    _, _, models = build_tracker(cfg, registry)
    assert isinstance(models[1], Braking) and models[1].rate == 0.5 and models[1].noise_density == 0.001


@pytest.mark.parametrize(
    ("mode", "match"),
    [
        (
            {"name": "coordinated_turn", "rate": 1.0},
            r"'coordinated_turn' has no parameter 'rate'; its parameters are \['max_rate', 'noise_density', 'rate_density'\]",
        ),
        ({"name": "coordinated_turn", "max_rate": "x"}, r"'coordinated_turn' with \{'max_rate': 'x'\}"),
        ({"name": "left_turn", "radius": -5.0}, "modes.radius"),
        ({"name": "zigzag"}, "unknown motion model 'zigzag'"),
    ],
)
def test_bad_mode_parameters_are_config_errors(mode, match):
    with pytest.raises(ConfigError, match=match):
        build_tracker(load_config(config("straight", mode)))
