"""Plugin loading: code-registered plugins, misspelt hooks, blocking, and faulty third-party distributions."""

import warnings

import pluggy
import pytest

import hybridtrack.core.plugins as plugins
from hybridtrack import hookimpl
from hybridtrack.core.plugins import PluginError, PluginInfo, PluginWarning, load_plugins
from hybridtrack.testing import LinearPositionSensor


class InlinePlugin:
    """A plugin object written in code: one sensor."""

    @hookimpl
    def register_sensors(self, registry):
        registry.add("inline_position", LinearPositionSensor)


class Misspelt:
    @hookimpl
    def register_motion_modles(self, registry):  # the spec is register_motion_models
        raise AssertionError("never called")


def _names(loaded):
    return [info.name for info in loaded.plugins]


@pytest.mark.parametrize("entrypoints", [False, True])
def test_a_plugin_registered_in_code_shows_up(entrypoints):
    loaded = load_plugins(extra=[InlinePlugin()], entrypoints=entrypoints, disabled=())
    assert loaded.registry.get("sensor", "inline_position") is LinearPositionSensor
    entry = loaded.registry.entry("sensor", "inline_position")
    assert (entry.plugin, entry.distribution, entry.version) == ("InlinePlugin", None, None)
    assert PluginInfo("InlinePlugin") in loaded.plugins
    assert loaded.problems == ()
    assert ("motion.linear_modes" in _names(loaded)) is entrypoints
    if entrypoints:
        assert loaded.registry.entry("motion_model", "straight").distribution == "hybridtrack"


def test_a_misspelt_hook_fails_via_check_pending_naming_the_plugin():
    with pytest.raises(PluginError, match=r"plugin 'Misspelt'.*register_motion_modles") as info:
        load_plugins(extra=[Misspelt()], entrypoints=False)
    assert isinstance(info.value.__context__, pluggy.PluginValidationError)


def test_environment_variable_blocks_the_builtin_motion_family(monkeypatch, fresh_default_plugins):
    assert "straight" in plugins.get_registry().names("motion_model")
    monkeypatch.setenv(plugins.DISABLE_ENV, "motion")
    assert "straight" in plugins.get_registry().names("motion_model"), "the default plugins are cached until reset()"
    plugins.reset()
    loaded = plugins.default_plugins()
    assert loaded.registry.names("motion_model") == []
    assert not [name for name in _names(loaded) if name.startswith("motion.")]
    assert loaded.manager.is_blocked("motion.linear_modes") and loaded.manager.is_blocked("motion.ship")
    assert "position" in loaded.registry.names("sensor"), "the other families still load"


def test_blocking_by_distribution_name_and_by_argument(monkeypatch):
    monkeypatch.setenv(plugins.DISABLE_ENV, " sensors , hybridtrack ")
    assert plugins.disabled_from_env() == {"sensors", "hybridtrack"}
    assert load_plugins().registry.entries() == []
    loaded = load_plugins(disabled=["sensors"])  # an explicit argument replaces the environment
    assert loaded.registry.names("sensor") == [] and loaded.registry.names("motion_model")
    assert load_plugins(extra=[InlinePlugin()], entrypoints=False, disabled=["InlinePlugin"]).plugins == ()


BROKEN_IMPORT = "import a_module_that_does_not_exist\n"

DUPLICATE = """
from hybridtrack import hookimpl
from hybridtrack.testing import LinearPositionSensor


class Shadow(LinearPositionSensor):
    '''Tries to take the built-in name.'''


@hookimpl
def register_sensors(registry):
    registry.add("position", Shadow)
    registry.add("dupe_only", Shadow)
"""

MISSPELT = """
from hybridtrack import hookimpl


@hookimpl
def register_sensor(registry):
    pass
"""

RAISES = """
from hybridtrack import hookimpl


@hookimpl
def register_detectors(registry):
    raise RuntimeError("boom")
"""


def _load_with_warnings(**kwargs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        loaded = load_plugins(**kwargs)
    return loaded, [w for w in caught if issubclass(w.category, PluginWarning)]


def test_broken_third_party_plugins_warn_and_the_others_load(install_distribution):
    install_distribution("hybridtrack-broken", {"broken": "ht_test_broken"}, {"ht_test_broken": BROKEN_IMPORT}, version="0.3")
    install_distribution("hybridtrack-dupe", {"dupe": "ht_test_dupe"}, {"ht_test_dupe": DUPLICATE}, version="2.0")
    install_distribution("hybridtrack-typo", {"typo": "ht_test_typo"}, {"ht_test_typo": MISSPELT})
    install_distribution("hybridtrack-raises", {"raises": "ht_test_raises"}, {"ht_test_raises": RAISES})

    loaded, caught = _load_with_warnings()
    messages = [str(w.message) for w in caught]
    assert len(messages) == 4, messages
    assert list(loaded.problems) == messages

    (broken,) = [m for m in messages if "'broken'" in m]
    assert "hybridtrack-broken" in broken and "failed to import" in broken and "a_module_that_does_not_exist" in broken
    (dupe,) = [m for m in messages if "'dupe'" in m]
    assert "hybridtrack-dupe" in dupe and "'position'" in dupe and "already registered by plugin 'sensors.position'" in dupe
    (typo,) = [m for m in messages if "'typo'" in m]
    assert "hybridtrack-typo" in typo and "register_sensor" in typo
    (raises,) = [m for m in messages if "'raises'" in m]
    assert "hybridtrack-raises" in raises and "register_detectors" in raises and "boom" in raises

    names = _names(loaded)
    assert {"motion.linear_modes", "sensors.position", "dupe", "raises"} <= set(names)
    assert "broken" not in names and "typo" not in names
    # the built-in keeps its name although 'dupe' sorts before 'sensors'; dupe's other component loads
    assert loaded.registry.entry("sensor", "position").plugin == "sensors.position"
    dupe_only = loaded.registry.entry("sensor", "dupe_only")
    assert (dupe_only.plugin, dupe_only.distribution, dupe_only.version) == ("dupe", "hybridtrack-dupe", "2.0")
    assert "straight" in loaded.registry.names("motion_model")


def test_strict_loading_raises_the_first_problem(install_distribution):
    install_distribution("hybridtrack-broken", {"broken": "ht_test_broken2"}, {"ht_test_broken2": BROKEN_IMPORT})
    with pytest.raises(PluginError, match="plugin 'broken' \\(distribution hybridtrack-broken\\) failed to import"):
        load_plugins(strict=True)


def test_a_broken_third_party_plugin_can_be_disabled(install_distribution):
    install_distribution("hybridtrack-broken", {"broken": "ht_test_broken3"}, {"ht_test_broken3": BROKEN_IMPORT})
    loaded, caught = _load_with_warnings(disabled=["hybridtrack-broken"])
    assert caught == [] and loaded.problems == ()
    assert loaded.manager.is_blocked("broken")


def test_one_plugin_module_can_be_blocked_by_its_entry_point_name():
    loaded = load_plugins(disabled=["filters.kalman"])
    assert "kalman" not in loaded.registry.names("estimator") and "information" in loaded.registry.names("estimator")
    assert loaded.problems == ()


def test_algorithms_register_through_their_entry_point_like_any_plugin():
    loaded = load_plugins(disabled=())
    for name in ("imm", "gpb1", "gpb2", "known_switch", "unknown_change", "known_modes"):
        entry = loaded.registry.entry("algorithm", name)
        assert (entry.plugin, entry.distribution) == ("algorithms", "hybridtrack")
    imm = plugins.resolve("algorithm", ("imm", {"modes": ["straight", "stop"], "sojourn": 10.0, "sensors": [LinearPositionSensor()]}))
    assert (imm.method, imm.name) == ("imm", "imm")
    assert load_plugins(disabled=["algorithms"]).registry.names("algorithm") == []


class Hello:
    """A plugin object adding a command."""

    @hookimpl
    def register_commands(self, commands):
        commands.add("hello", "say hello", lambda parser: parser.add_argument("who"), lambda args: print(f"hello {args.who}"))


CLASH = """
from hybridtrack import hookimpl


@hookimpl
def register_commands(commands):
    commands.add("plugins", "takes a built-in's name", lambda parser: None, lambda args: 1)
    commands.add("extra_listing", "its other command", lambda parser: None, lambda args: 0)
"""


def test_commands_come_through_the_hook_and_the_builtins_are_not_listed_as_plugins():
    from hybridtrack import cli

    loaded = load_plugins(builtins=cli.builtin_plugins(), extra=[Hello()], entrypoints=False)
    assert list(loaded.commands) == ["plugins", "simulate", "inspect", "run", "track", "fit", "hello"]
    assert loaded.commands["hello"].plugin == "Hello" and loaded.commands["plugins"].plugin == "hybridtrack.cli.plugins"
    assert [info.name for info in loaded.plugins] == ["Hello"] and loaded.problems == ()


def test_a_command_name_clash_keeps_the_builtin(install_distribution):
    from hybridtrack import cli

    install_distribution("hybridtrack-clash", {"clash": "ht_test_clash"}, {"ht_test_clash": CLASH})
    loaded, caught = _load_with_warnings(builtins=cli.builtin_plugins())
    (message,) = [str(w.message) for w in caught]
    assert "command 'plugins' of plugin 'clash' is already added by plugin 'hybridtrack.cli.plugins'" in message
    assert loaded.commands["plugins"].plugin == "hybridtrack.cli.plugins" and loaded.commands["extra_listing"].plugin == "clash"

    class Clash:
        @hookimpl
        def register_commands(self, commands):
            commands.add("run", "again", lambda parser: None, lambda args: 0)

    with pytest.raises(PluginError, match="command 'run' of plugin 'Clash' is already added"):  # written in code: raised
        load_plugins(builtins=cli.builtin_plugins(), extra=[Clash()], entrypoints=False)
