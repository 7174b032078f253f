"""``make screenshots``: the recordings of the demo and every example, rendered by the real Rerun viewer into docs/images/.

    python tools/screenshots.py [--only NAME …] [--work DIR] [--images docs/images] [--no-install]

1. **What it needs.** The viewer renders with Vulkan; without a GPU that is
   Mesa's software rasterizer lavapipe (Debian package ``mesa-vulkan-drivers``).
   The fallback path (below) also needs an X server: ``xvfb`` (with ``xauth``)
   and ``libgl1-mesa-dri``.  Missing packages are installed with
   ``apt-get install -y`` when the script runs as root on a Debian-like system
   (otherwise it stops, naming the packages).
2. **The recordings** (in ``--work``, default a temporary folder), each made by
   the command a user would type: ``examples/demo.py``,
   ``examples/example1_unknown_change.py``, ``examples/bearings_only.py``,
   ``hybridtrack run examples/monte_carlo.py --record-runs 0 --summary-recording``
   (one recorded run and the campaign's summary recording) and
   ``hybridtrack track`` on the Solent AIS file with ``examples/ships.toml`` and
   with ``examples/aircraft.toml`` (its estimator, an IMM, on two vessels: the
   file's reader section swapped for the Solent preset), and ``hybridtrack track`` on the Solent file without
   identities with ``examples/multitarget_solent.toml`` (every vessel a track).
3. **The screenshot.** For each recording a fresh headless viewer
   (``rerun --headless``, the same binary as the SDK in this environment, on a
   free port, ``HOME`` and ``XDG_RUNTIME_DIR`` in a temporary folder so nothing
   is written to the user's home) opens the file with the layout embedded in
   it; :class:`rerun.experimental.ViewerClient` moves the time cursor to the end
   of the ``utc`` timeline for a recording of real time stamps (the timeline its
   blueprint opens on), else of ``step`` (``run`` for a campaign summary),
   pauses, and saves the window (1920×1080).  If the headless viewer cannot
   start, ``xvfb-run rerun FILE --new --screenshot-to PNG --window-size
   1600x900`` takes the shot instead (the time cursor then stays where the
   viewer puts it).
4. **The PNG** is reduced to 128 colours (Pillow, median cut) and, if still
   above 300 kB, scaled down until it fits; it goes to
   ``docs/images/rerun_<name>.png``.  The views' own warnings (entities they
   cannot show) are printed.
"""

from __future__ import annotations

import argparse
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
RERUN = BIN / "rerun"
HYBRIDTRACK = BIN / "hybridtrack"
SOLENT = ROOT / "data" / "solent_ais" / "SolentAIS_20160112_130211.csv"
#: the vessels of the Solent file tracked for the figures: the ferry of docs/real_data.md and a second ship
VESSELS = ("235007473", "235013375")
#: Debian packages: software Vulkan (lavapipe) for the headless viewer, X server and GL for the fallback
PACKAGES = ("mesa-vulkan-drivers", "libgl1-mesa-dri", "xvfb", "xauth")
MAX_BYTES = 300_000
#: seconds after the viewer's start before the shot (its start-up notifications fade in about five)
SETTLE = 7.0
WINDOW = "1600x900"
#: the timeline whose end the cursor goes to: the first of these a recording has (``utc``: real time stamps)
CURSOR_TIMELINES = ("utc", "step", "run", "time")


def log(message: str) -> None:
    print(f"screenshots: {message}", file=sys.stderr, flush=True)


def missing_packages() -> list[str]:
    """The packages of :data:`PACKAGES` that look absent (lavapipe's ICD file, the Xvfb binary)."""
    missing = []
    icd = Path("/usr/share/vulkan/icd.d")
    if not any(icd.glob("lvp_icd*.json")):
        missing += ["mesa-vulkan-drivers", "libgl1-mesa-dri"]
    if shutil.which("Xvfb") is None or shutil.which("xvfb-run") is None:
        missing += ["xvfb", "xauth"]
    return missing


def install_packages(allowed: bool) -> None:
    missing = missing_packages()
    if not missing:
        return
    if not allowed:
        raise SystemExit(f"screenshots: missing system packages {' '.join(missing)} (--no-install given)")
    if shutil.which("apt-get") is None or os.geteuid() != 0:
        raise SystemExit(f"screenshots: install these Debian packages first (as root): apt-get install -y {' '.join(missing)}")
    log(f"installing {' '.join(missing)} with apt-get")
    environment = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    subprocess.run(["apt-get", "update"], check=True, env=environment, stdout=subprocess.DEVNULL)
    subprocess.run(
        ["apt-get", "install", "-y", "--no-install-recommends", *missing], check=True, env=environment, stdout=subprocess.DEVNULL
    )


def run(command: list, environment: dict) -> None:
    log("$ " + " ".join(str(part) for part in command))
    subprocess.run([str(part) for part in command], check=True, cwd=ROOT, env=environment, stdout=subprocess.DEVNULL)


def aircraft_on_solent(work: Path) -> Path:
    """examples/aircraft.toml with its [reader] swapped for the Solent AIS preset (the rest as written)."""
    text = (ROOT / "examples" / "aircraft.toml").read_text(encoding="utf-8")
    head, reader, rest = text.partition("\n[reader]\n")  # the table header on its own line (not a mention in a comment)
    body, _, after = rest.partition("\n[")
    reader_lines = ['preset = "solent_ais"'] + [
        line for line in body.splitlines() if line.split("=")[0].strip() in ("max_speed", "jump_tolerance", "min_reports")
    ]
    config = work / "aircraft_on_solent.toml"
    config.write_text(head + reader + "\n".join(reader_lines) + "\n\n[" + after, encoding="utf-8")
    return config


def make_recordings(work: Path, only: set[str], environment: dict) -> dict[str, Path]:
    """name → recording file, made in ``work`` by the examples' own commands."""
    python = sys.executable
    recordings: dict[str, Path] = {}

    def wanted(name: str) -> bool:
        return not only or name in only

    if wanted("demo"):
        run([python, ROOT / "examples" / "demo.py", "--out", work / "demo.rrd"], environment)
        recordings["demo"] = work / "demo.rrd"
    if wanted("example1"):
        run([python, ROOT / "examples" / "example1_unknown_change.py", "--out", work / "example1.rrd"], environment)
        recordings["example1"] = work / "example1.rrd"
    if wanted("bearings_only"):
        run([python, ROOT / "examples" / "bearings_only.py", "--out", work / "bearings_only.rrd"], environment)
        recordings["bearings_only"] = work / "bearings_only.rrd"
    if wanted("monte_carlo") or wanted("monte_carlo_summary"):
        out = work / "monte_carlo"
        run(
            [HYBRIDTRACK, "run", ROOT / "examples" / "monte_carlo.py", "--n", "40", "--executor", "inline", "--out", out]
            + ["--record-runs", "0", "--summary-recording", "--no-progress"],
            environment,
        )
        recordings["monte_carlo"] = out / "recordings" / "run_00000.rrd"
        recordings["monte_carlo_summary"] = out / "summary.rrd"
    for name, config in (("ships", ROOT / "examples" / "ships.toml"), ("aircraft", None)):
        if not wanted(name) and not any(wanted(f"{name}_{vessel}") for vessel in VESSELS):
            continue
        config = config or aircraft_on_solent(work)
        ids = [argument for vessel in VESSELS for argument in ("--id", vessel)]
        run([HYBRIDTRACK, "track", SOLENT, "--config", config, "--out", work / name, *ids, "--no-progress"], environment)
        for vessel in VESSELS:
            recordings[f"{name}_{vessel}"] = work / name / f"{vessel}.rrd"
    if wanted("multitarget_solent"):  # every report without its MMSI: many tracks at once on the map view
        out = work / "multitarget_solent"
        run(
            [HYBRIDTRACK, "track", SOLENT, "--config", ROOT / "examples" / "multitarget_solent.toml", "--out", out, "--no-progress"],
            environment,
        )
        recordings["multitarget_solent"] = out / "tracks.rrd"
    return recordings


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def headless_screenshot(recording: Path, png: Path, timeout: float = 120.0) -> list[str]:
    """Open ``recording`` in a fresh headless viewer, put the time cursor at the end, save the window; the views' warnings.

    The file is loaded in the background (``navigate=False``) and shown only once loaded; the cursor goes to
    the end of the first of :data:`CURSOR_TIMELINES` the file has: ``utc`` (real time stamps: the clock time the
    embedded blueprint opens on), ``step``, ``run`` (a campaign summary), ``time``.  The timeline the viewer
    opened the file on is logged.  The shot is taken at least :data:`SETTLE` seconds after the viewer started,
    when its start-up notifications have faded.
    """
    from rerun.experimental import ViewerClient

    started = time.monotonic()
    client = ViewerClient.spawn(headless=True, port=free_port(), hide_welcome_screen=True, executable_path=str(RERUN))
    try:
        client.open(str(recording), navigate=False)
        deadline = time.monotonic() + timeout
        while True:
            state = client.get_state()
            if not state.loading and state.recordings and any(t.end is not None for t in state.recordings[0].timelines):
                break
            if time.monotonic() > deadline:
                raise TimeoutError(f"{recording}: the viewer did not finish loading within {timeout:g} s")
            time.sleep(0.3)
        shown = state.recordings[0]
        client.set_location(shown.location)
        log(f"{recording.name}: the viewer opened it on the {shown.current_timeline!r} timeline")
        timelines = {timeline.name: timeline for timeline in shown.timelines}
        for name in CURSOR_TIMELINES:
            timeline = timelines.get(name)
            if timeline is None or timeline.end is None:
                continue
            if timeline.time_type == "duration":
                client.set_time(name, duration=timeline.end / 1e9, play_state="paused")
            elif timeline.time_type == "timestamp":  # integer ns since the Unix epoch, kept exact
                client.set_time(name, timestamp=np.datetime64(int(timeline.end), "ns"), play_state="paused")
            else:
                client.set_time(name, sequence=int(timeline.end), play_state="paused")
            break
        time.sleep(max(1.0, SETTLE - (time.monotonic() - started)))  # lay out the views; let the notifications fade
        client.save_screenshot(str(png))
        state = client.get_state()
        return [f"view {view.name!r}: {report.severity}: {report.summary}" for view in state.views for report in view.reports]
    finally:
        client.quit()


def xvfb_screenshot(recording: Path, png: Path, environment: dict) -> None:
    command = ["xvfb-run", "-a", "-s", "-screen 0 1920x1200x24", str(RERUN), str(recording), "--new"]
    command += ["--screenshot-to", str(png), "--window-size", WINDOW]
    subprocess.run(command, check=True, env=environment, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=300)


def shrink(raw: Path, png: Path, limit: int = MAX_BYTES) -> int:
    """``raw`` reduced to 128 colours (scaled down by 0.85 at a time while above ``limit`` bytes) into ``png``; its size."""
    from PIL import Image

    image = Image.open(raw).convert("RGB")
    scale = 1.0
    while True:
        size = (round(image.width * scale), round(image.height * scale))
        reduced = (image if scale == 1.0 else image.resize(size, Image.LANCZOS)).quantize(colors=128, method=Image.Quantize.MEDIANCUT)
        png.parent.mkdir(parents=True, exist_ok=True)
        reduced.save(png, optimize=True)
        if png.stat().st_size <= limit or scale < 0.2:
            return png.stat().st_size
        scale *= 0.85


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=[], metavar="NAME", help="only these (demo, example1, bearings_only, monte_carlo, …)")
    parser.add_argument("--work", type=Path, help="where the recordings are made (default: a temporary folder, removed)")
    parser.add_argument("--images", type=Path, default=ROOT / "docs" / "images", help="where the PNGs go (default docs/images)")
    parser.add_argument("--no-install", action="store_true", help="do not apt-get install missing system packages")
    args = parser.parse_args(argv)

    install_packages(not args.no_install)
    scratch = Path(tempfile.mkdtemp(prefix="hybridtrack-screenshots-"))
    home = scratch / "home"
    runtime = scratch / "runtime"
    home.mkdir()
    runtime.mkdir(mode=0o700)
    # the rerun CLI and viewer write analytics and state under HOME: keep them out of the user's
    # RUST_LOG=error: fewer viewer notifications on the screenshots and a quiet terminal
    os.environ.update(HOME=str(home), XDG_RUNTIME_DIR=str(runtime), MPLBACKEND="Agg", RUST_LOG="error")
    environment = dict(os.environ)
    work = args.work or scratch / "recordings"
    work.mkdir(parents=True, exist_ok=True)
    try:
        recordings = make_recordings(work, set(args.only), environment)
        for name, recording in recordings.items():
            raw = scratch / f"{name}.raw.png"
            try:
                warnings = headless_screenshot(recording, raw)
            except Exception as error:  # noqa: BLE001 - any failure of the headless viewer: try the X server path
                log(f"{name}: headless viewer failed ({error}); trying xvfb-run … --screenshot-to")
                xvfb_screenshot(recording, raw, environment)
                warnings = []
            png = args.images / f"rerun_{name}.png"
            size = shrink(raw, png)
            log(f"{name}: {png.relative_to(ROOT) if png.is_relative_to(ROOT) else png} ({size / 1000:.0f} kB)")
            for warning in warnings:
                log(f"  {warning}")
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
