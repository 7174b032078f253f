"""main() on the process's own command line freezes the collector's objects (a faster run and exit); main(argv) in a
test or a notebook leaves the collector alone."""

import gc
import subprocess
import sys

from hybridtrack.cli import main


def test_main_with_argv_leaves_the_collector_alone(capsys):
    before = gc.get_freeze_count()
    assert main(["plugins"]) == 0
    assert gc.get_freeze_count() == before


def test_main_as_the_program_freezes_what_it_loaded():
    code = "import gc, sys; from hybridtrack.cli import main; sys.argv = ['hybridtrack', 'plugins']; s = main(); print(s, gc.get_freeze_count())"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    status, frozen = done.stdout.split()[-2:]
    assert status == "0" and int(frozen) > 10_000  # the plugins' modules and what the command made
