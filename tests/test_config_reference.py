"""The configuration reference (hybridtrack/apps/config_reference.py, docs/config.md) against the parser.

Checked: its keys are ``hybridtrack.apps.tracking.CONFIG_KEYS``, section by section, so a key the parser accepts
without an entry fails (and an entry of a key it refuses); docs/config.md is the generated text; every default
shown is TOML that reads back as the value the code fills in; the page's smallest configuration runs.
"""

import inspect
import tomllib
from pathlib import Path

import pytest

from hybridtrack.apps import config_reference, tracking
from hybridtrack.io.track_files import read_tracks

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "config.md"


@pytest.fixture(scope="module")
def entries():
    return config_reference.reference()


@pytest.fixture(scope="module")
def markdown():
    return config_reference.reference_markdown()


def test_the_keys_are_those_the_parser_accepts_section_by_section(entries):
    assert config_reference.reference_differences(entries) == {}
    assert list(entries) == list(tracking.CONFIG_KEYS)


def test_a_key_accepted_without_an_entry_fails(entries, monkeypatch):
    monkeypatch.setitem(tracking.CONFIG_KEYS, "prior", tracking.CONFIG_KEYS["prior"] | {"acceleration_sigma"})
    with pytest.raises(ValueError, match=r"\[prior\] accepted without an entry: \['acceleration_sigma'\]"):
        config_reference.check_reference(entries)


def test_an_entry_of_a_key_not_accepted_fails(entries):
    described = {**entries, "segments": {**entries["segments"], "min_duration": entries["segments"]["by"]}}
    with pytest.raises(ValueError, match=r"\[segments\] described but not accepted: \['min_duration'\]"):
        config_reference.check_reference(described)


def test_docs_config_md_is_the_generated_page(markdown):
    assert PAGE.read_text(encoding="utf-8") == markdown, f"docs/config.md is out of date: run {config_reference.COMMAND}"


def test_every_key_has_a_row_on_the_page(entries, markdown):
    for section, keys in entries.items():
        block = markdown.split(f"## `[{section}]`", 1)[1].split("\n## ", 1)[0]
        assert [line.split("`")[1] for line in block.splitlines() if line.startswith("| `")] == list(keys)


def test_defaults_shown_are_the_code_s_and_read_back_as_toml(entries):
    probe = config_reference.filled_defaults()
    expected = {
        ("reader", "time"): inspect.signature(read_tracks).parameters["time"].default,
        ("reader", "min_reports"): probe["imm"]["min_reports"],
        ("altitude", "sigma"): tracking.ALTITUDE_DEFAULTS["sigma"],
        ("prior", "turn_rate_sigma"): tracking.TURN_RATE_SIGMA,
        ("estimator", "sojourn"): probe["imm"]["estimator"]["sojourn"],
        ("estimator", "bank_size"): probe["unknown_change"]["estimator"]["bank_size"],
    }
    for (section, key), value in expected.items():
        assert entries[section][key].default() == value, (section, key)
    for section, keys in entries.items():
        for key, entry in keys.items():
            value = entry.default() if entry.default is not None else None
            if value is not None:
                read = tomllib.loads(f"v = {config_reference.toml_value(value)}")["v"]
                assert read == (list(value) if isinstance(value, tuple) else value), (section, key)


def test_the_derived_defaults_follow_the_parser():
    config = tracking.load_config({"measurement": {"sigma": 3.0}, "estimator": {"algorithm": "imm", "modes": ["straight"]}})
    page = PAGE.read_text(encoding="utf-8")
    assert f"{config['prior']['position_sigma'] / 3.0:g} × `[measurement] sigma`" in page
    motion = {"by": "motion", "turn_rate_on": 2.0, "stop_speed": 3.0}
    segments = tracking.load_config(
        {"measurement": {"sigma": 3.0}, "segments": motion, "estimator": {"algorithm": "imm", "modes": ["straight"]}}
    )["segments"]
    assert f"{segments['turn_rate_off'] / 2.0:g} × `turn_rate_on`" in page and f"{segments['go_speed'] / 3.0:g} × `stop_speed`" in page


def test_the_smallest_configuration_on_the_page_runs():
    config = tracking.load_config(tomllib.loads(config_reference.MINIMAL_EXAMPLE))
    estimator, _, models = tracking.build_tracker(config)
    assert config["estimator"]["algorithm"] == "imm" and [m.name for m in models] == ["straight", "coordinated_turn"]
    assert "omega" in estimator.layout


def test_a_value_toml_cannot_write_is_refused():
    with pytest.raises(TypeError, match=r"value: expected a TOML string, number, boolean, array or table, got None"):
        config_reference.toml_value(None)
