"""Shared fixtures: the rerun CLI with a throw-away HOME (it writes analytics files there)."""

import subprocess
import sys
from pathlib import Path

import pytest

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
