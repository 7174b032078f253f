"""The registry: lookup, creation, duplicates and unknown names."""

import pytest

from hybridtrack.core.kinds import KINDS
from hybridtrack.core.registry import DuplicateComponentError, Entry, Registry, UnknownComponentError


class Documented:
    """First line of the summary.

    More text.
    """

    def __init__(self, radius: float = 1.0):
        self.radius = radius


def undocumented():
    return None


def _registry() -> Registry:
    registry = Registry()
    registry.add(Entry("motion_model", "left_turn", Documented, "motion", "hybridtrack", "0.1.0"))
    registry.add(Entry("motion_model", "straight", undocumented, "motion", "hybridtrack", "0.1.0"))
    return registry


def test_lookup_and_create():
    registry = _registry()
    assert registry.get("motion_model", "left_turn") is Documented
    assert registry.create("motion_model", "left_turn", radius=5.0).radius == 5.0
    assert registry.names("motion_model") == ["left_turn", "straight"]
    assert registry.names("sensor") == []
    assert [e.name for e in registry.entries()] == ["left_turn", "straight"]


def test_unknown_name_lists_the_known_ones():
    registry = _registry()
    with pytest.raises(UnknownComponentError) as info:
        registry.get("motion_model", "left_trun")
    assert str(info.value) == "unknown motion_model 'left_trun'; known: left_turn, straight"
    assert isinstance(info.value, KeyError)
    with pytest.raises(UnknownComponentError, match="unknown sensor 'radar'; known: none"):
        registry.create("sensor", "radar")


def test_unknown_kind_lists_the_kinds():
    with pytest.raises(ValueError, match="unknown component kind 'filter'; kinds are " + ", ".join(KINDS)):
        Registry().names("filter")
    with pytest.raises(ValueError, match="unknown component kind 'filter'"):
        Registry().add(Entry("filter", "kalman", Documented, "p"))


def test_duplicate_names_both_plugins_and_distributions():
    registry = _registry()
    with pytest.raises(DuplicateComponentError) as info:
        registry.add(Entry("motion_model", "straight", Documented, "zigzag", "hybridtrack-zigzag", "1.0"))
    message = str(info.value)
    assert "plugin 'zigzag' (distribution hybridtrack-zigzag)" in message
    assert "already registered by plugin 'motion' (distribution hybridtrack)" in message
    assert registry.get("motion_model", "straight") is undocumented  # the first one stays
    registry.add(Entry("sensor", "straight", Documented, "zigzag"))  # same name, other kind: fine


@pytest.mark.parametrize(
    "name, factory, message", [("", Documented, "non-empty string"), (3, Documented, "non-empty string"), ("x", 42, "not callable")]
)
def test_bad_entries_are_rejected(name, factory, message):
    with pytest.raises(ValueError, match=message):
        Registry().add(Entry("sensor", name, factory, "p"))


def test_summary_is_the_first_docstring_line():
    registry = _registry()
    assert registry.entry("motion_model", "left_turn").summary == "First line of the summary."
    assert registry.entry("motion_model", "straight").summary == ""


def test_registrar_reports_errors_and_keeps_going():
    registry = _registry()
    errors = []
    registrar = registry.bind("motion_model", "zigzag", "hybridtrack-zigzag", "1.0", errors.append)
    registrar.add("straight", undocumented)
    registrar.add("weave", undocumented)
    registrar.add("swirl", Documented)  # a class, and not a MotionModel: rejected at registration
    assert len(errors) == 2 and isinstance(errors[0], DuplicateComponentError)
    assert isinstance(errors[1], TypeError) and "does not implement hybridtrack.core.interfaces.MotionModel" in str(errors[1])
    entry = registry.entry("motion_model", "weave")
    assert (entry.plugin, entry.distribution, entry.version) == ("zigzag", "hybridtrack-zigzag", "1.0")
    assert "swirl" not in registry.names("motion_model")


def test_one_table_of_kinds_drives_hooks_registry_and_checks():
    from hybridtrack.core import hookspecs
    from hybridtrack.core.algorithm import Algorithm
    from hybridtrack.testing.contracts import _CHECKS

    assert list(KINDS) == ["motion_model", "sensor", "estimator", "detector", "solver", "algorithm"]
    assert KINDS["algorithm"].interface is Algorithm and KINDS["algorithm"].hook == "register_algorithms"
    for kind in KINDS.values():
        assert callable(getattr(hookspecs, kind.hook)), f"no hookspec {kind.hook} for kind {kind.name}"
    assert set(_CHECKS) == set(KINDS) and Registry().names("algorithm") == []


def test_a_composite_component_resolves_its_parts_in_the_registry_it_came_from():
    """Registry.create hands itself to a factory with a ``registry`` parameter: dynamic_threshold built from a
    registry holding a private detector finds it there (the default registry does not know it)."""
    from hybridtrack.core.plugins import get_registry
    from hybridtrack_plugins.detectors.dynamic_threshold import DynamicThreshold
    from hybridtrack_plugins.detectors.glr import GLR

    class PrivateGLR(GLR):
        name = "private_glr"

    registry = Registry()
    registry.add(Entry("detector", "private_glr", PrivateGLR, "test"))
    registry.add(Entry("detector", "dynamic_threshold", DynamicThreshold, "test"))
    wrapper = registry.resolve("detector", ("dynamic_threshold", {"detector": "private_glr"}))
    assert type(wrapper.detector) is PrivateGLR
    assert "private_glr" not in get_registry().names("detector")
    with pytest.raises(KeyError, match="unknown detector 'private_glr'"):
        DynamicThreshold(detector="private_glr")  # built directly: the default registry
    assert type(DynamicThreshold(detector="private_glr", registry=registry).detector) is PrivateGLR
