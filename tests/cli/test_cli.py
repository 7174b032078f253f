"""The command line: version, the plugins listing (table and JSON), problems on stderr, the command registry."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

import hybridtrack
from hybridtrack import cli
from hybridtrack.cli.plugins import JSON_KEYS
from hybridtrack.core.kinds import KINDS
from hybridtrack.core.plugins import PluginError

SCRIPT = Path(sys.executable).with_name("hybridtrack")


def run(capsys, *argv):
    status = cli.main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def test_version(capsys):
    status, out, _ = run(capsys, "--version")
    assert status == 0 and out.strip() == f"hybridtrack {hybridtrack.__version__}"


def test_no_command_prints_help_and_fails(capsys):
    status, _, err = run(capsys)
    assert status == 2 and "plugins" in err and "usage: hybridtrack" in err


def test_unknown_command_is_a_usage_error(capsys):
    status, _, err = run(capsys, "plugns")
    assert status == 2 and "invalid choice: 'plugns'" in err


def test_plugins_json_lists_every_registered_component(capsys):
    status, out, err = run(capsys, "plugins", "--json")
    assert status == 0 and err == ""
    listing = json.loads(out)
    assert all(tuple(item) == JSON_KEYS for item in listing)
    assert all(item["kind"] in KINDS for item in listing)
    registry = hybridtrack.core.plugins.load_plugins().registry
    assert {(i["kind"], i["name"]) for i in listing} == {(e.kind, e.name) for e in registry.entries()}
    algorithms = {i["name"] for i in listing if i["kind"] == "algorithm"}
    assert {"imm", "gpb1", "gpb2", "known_switch", "unknown_change", "known_modes"} <= algorithms
    straight = next(i for i in listing if i["name"] == "straight")
    assert straight == {
        "plugin": "motion.linear_modes",
        "distribution": "hybridtrack",
        "version": hybridtrack.__version__,
        "kind": "motion_model",
        "name": "straight",
    }


def test_plugins_table_shows_plugins_components_and_summaries(capsys):
    status, out, _ = run(capsys, "plugins")
    lines = out.splitlines()
    assert status == 0 and lines[0].split() == ["plugin", "distribution", "version", "kind", "name", "summary"]
    (straight,) = [line for line in lines if "straight" in line.split()]
    assert straight.split()[:5] == ["motion.linear_modes", "hybridtrack", hybridtrack.__version__, "motion_model", "straight"]
    summary = hybridtrack.get_registry().entry("motion_model", "straight").summary
    assert summary and straight.endswith(summary)
    for family in ("motion", "sensors", "filters", "detectors", "solvers"):
        assert any(line.split()[0].startswith(family + ".") for line in lines[2:]), f"plugin family {family} missing from the table"
    (imm,) = [line for line in lines if "imm" in line.split()]
    assert imm.split()[:5] == ["algorithms", "hybridtrack", hybridtrack.__version__, "algorithm", "imm"]


def test_loading_problems_go_to_stderr(capsys, install_distribution):
    install_distribution("hybridtrack-broken", {"broken": "ht_cli_broken"}, {"ht_cli_broken": "raise ImportError('no luck')\n"})
    status, out, err = run(capsys, "plugins", "--json")
    assert status == 0
    assert err.startswith("warning: plugin 'broken' (distribution hybridtrack-broken) failed to import")
    assert "no luck" in err and err.count("\n") == 1
    assert any(item["name"] == "straight" for item in json.loads(out)), "the other plugins are still listed"


def test_disabled_plugins_are_not_listed(capsys, monkeypatch):
    monkeypatch.setenv("HYBRIDTRACK_DISABLE_PLUGINS", "motion")
    _, out, _ = run(capsys, "plugins", "--json")
    listing = json.loads(out)
    assert not [item for item in listing if item["plugin"].startswith("motion.")] and listing


def test_commands_come_through_the_hook_and_names_are_unique(monkeypatch):
    assert list(cli.commands()) == ["plugins", "simulate", "inspect", "run", "track", "fit"]
    monkeypatch.setattr(cli, "COMMAND_MODULES", cli.COMMAND_MODULES + ("hybridtrack.cli.plugins",))
    with pytest.raises(PluginError, match="hybridtrack.cli.plugins"):
        cli.commands()


HELLO = """
from hybridtrack import hookimpl
from hybridtrack.core.commands import UsageError


def run(args):
    if args.who == "nobody":
        raise UsageError("who: expected somebody")
    print(f"hello {args.who}")
    return 5


@hookimpl
def register_commands(commands):
    commands.add("hello", "say hello", lambda parser: parser.add_argument("who"), run)
"""


def test_a_third_party_command_plugs_in_through_the_hook(capsys, install_distribution):
    install_distribution("hybridtrack-hello", {"hello": "ht_cli_hello"}, {"ht_cli_hello": HELLO})
    status, out, _ = run(capsys, "--help")
    assert status == 0 and "say hello" in out
    assert run(capsys, "hello", "world")[:2] == (5, "hello world\n")
    status, _, err = run(capsys, "hello", "nobody")
    assert status == 2 and err == "hybridtrack hello: error: who: expected somebody\n"
    status, _, err = run(capsys, "plugins", "--json")
    assert status == 0 and err == ""


def test_version_loads_no_plugin(capsys, monkeypatch):
    def refuse():
        raise AssertionError("--version must not load the plugins")

    monkeypatch.setattr(cli, "commands", refuse)
    for argv in (["--version"], ["--vers"]):
        status, out, _ = run(capsys, *argv)
        assert status == 0 and out.strip() == f"hybridtrack {hybridtrack.__version__}"
    with pytest.raises(AssertionError, match="must not load"):
        cli.main(["plugins", "--version"])


def test_a_new_command_plugs_into_the_parser(capsys):
    seen = []
    extra = cli.Command("echo", "repeat a word", lambda p: p.add_argument("word"), lambda args: seen.append(args.word) or 3)
    parser = cli.build_parser({"echo": extra})
    args = parser.parse_args(["echo", "hello"])
    assert args.run(args) == 3 and seen == ["hello"]


@pytest.mark.skipif(not SCRIPT.exists(), reason=f"console script not installed at {SCRIPT}")
def test_installed_console_script():
    result = subprocess.run([str(SCRIPT), "plugins", "--json"], capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 0, result.stderr
    listing = json.loads(result.stdout)
    assert {"straight", "position"} <= {item["name"] for item in listing}
