"""Every ``sh`` block of docs/ runs as written, page after page in the site's order, in one fresh
folder: no command fails, none warns of frames showing nodata or ground off the map, none is
refused because an earlier line wrote the same folder (each writing line has its own --out).

The ``air-sitl`` lines and ``python bridges/...`` lines run (other programs, such as ``pip``,
``ray`` or ``docker``, are skipped: the README tour and CI cover installation). A line ending in
``&`` runs in the background beside the next lines of its block, and is waited for (then
stopped) at the block's end. Lines meant as templates (``PLAN``, ``W,S,E,N``) are fenced as
``text``, not ``sh``: a placeholder in an ``sh`` block fails the first test.

Pages whose lines need the internet (``ONLINE_PAGES``: real-naip.md's NAIP years from Planetary
Computer) are not run here; their lines are tested against a local STAC API elsewhere.

What the runner changes, because as written the lines take minutes (CI's budget) or use
the ports of a real ground station:

- ``missions/`` holds short versions of AIR's 12 plans: the same names and homes, 60 m high,
  a 30 m capture leg (about 100 frames) instead of 1-5 km; every flight takes seconds.
- ``--scenarios all`` (and ``air``) flies UC-200 only; a ``fly`` with ``--altitude-offset``
  starts in the air (``--air-start``: its climb of 800 m takes minutes), and so does a ``fly``
  in lockstep with a localizer (``--wait-for``: with an aid the camera runs for the whole
  flight, and the localizer answers each of the climb's 1,800 frames too, 20 s of CPU against
  10 s from the air); ``dataset``,
  ``bench`` and ``sweep`` get ``--missions missions`` (the short plans, not the checkout's).
- ``map make`` writes at 2.5 m pixels (``--gsd-m 2.5``), and a ``--size-m`` window becomes 800 m
  square around the short flight from the nearest plan's home (a procedural map's cost grows
  with its area, whatever its pixels: 1300 x 3800 m took a minute of CPU at any pixel size;
  800 m took 0.6 s at 2.5 m pixels, 1.3 s at 5 m, where the coarser level draws a wider square).
  tests/docs/test_readme_tour.py checks the full window against the full plan.
- a SPEC from ``examples/`` is cut to its first value on every axis and 45 simulated seconds.
- ``serve`` gets ``--max-sim-time 5``, ``--no-video`` and a link on a port the kernel picks;
  the zenoh bus's default endpoint (tcp/127.0.0.1:7447) is replaced by a free port; a flight
  that waits for a localizer (``--wait-for``) waits up to 120 s for it to start, not 10 s,
  and a ``bridges/`` client waits up to 120 s for the simulator (``--wait 120``).
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from short_plans import write_short_plan

from air_sitl.frames import ned2geodetic
from air_sitl.mission.plan_file import load_mission
from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"
LINE_TIMEOUT_S = 600.0  # only a hung command gets there
PLACEHOLDER = re.compile(r"\b(PLAN|SPEC|DIR|HEAD|URL_OR\w*|W,S,E,N|tcp/A:P|127\.0\.0\.1:P)\b")
OFF_MAP = "nodata or ground off the map"
SHORT_ALT_M = 60.0  # the short plans' altitude: a climb of seconds
SHORT_WINDOW_M = 800  # map make's window around a short flight (its cost grows with the area)
# Pages whose lines need the internet (CI and this machine have none): each is run elsewhere.
ONLINE_PAGES = {
    "real-naip.md": "tests/maps/test_real_years.py runs its lines against a local STAC API",
}


def pages() -> list[Path]:
    """docs/ pages in the order of the site's navigation (mkdocs.yml)."""
    nav = yaml.safe_load((REPO / "mkdocs.yml").read_text(encoding="utf-8"))["nav"]
    found: list[str] = []

    def walk(node: object) -> None:
        if isinstance(node, str):
            found.append(node)
        elif isinstance(node, list):
            for item in node:
                walk(item)
        elif isinstance(node, dict):
            for value in node.values():
                walk(value)

    walk(nav)
    return [DOCS / name for name in found if name.endswith(".md")]


def sh_blocks(page: Path) -> list[list[str]]:
    """The command lines of each ``sh`` block (continuations joined, comments kept)."""
    text = page.read_text(encoding="utf-8")
    blocks = []
    for body in re.findall(r"^```sh\n(.*?)^```", text, re.S | re.M):
        joined = re.sub(r"\\\n\s*", "", body)
        blocks.append([ln for ln in joined.splitlines() if ln.strip() and not ln.startswith("#")])
    return blocks


def test_sh_blocks_hold_commands_not_templates() -> None:
    bad = [
        f"{page.name}: {line}"
        for page in pages()
        for block in sh_blocks(page)
        for line in block
        if PLACEHOLDER.search(line.split("#", 1)[0])
    ]
    assert not bad, "templates fenced as sh (fence them as text):\n" + "\n".join(bad)


def short_missions(folder: Path) -> None:
    """AIR's 12 plans, short: each one's home, 60 m high, a 30 m capture leg north."""
    folder.mkdir()
    for plan in sorted((REPO / "missions").glob("*.plan")):
        mission = load_mission(plan)
        home = mission.planned_home
        assert home is not None
        write_short_plan(
            folder / plan.name,
            GeoPoint(lat_deg=home.lat_deg, lon_deg=home.lon_deg, alt_amsl_m=home.alt_amsl_m),
            leg_m=30.0,
            alt_m=SHORT_ALT_M,
            leg="north",
            lead_m=150.0,
        )


def short_flight_area(origin: str) -> str:
    """LAT,LON of the middle of the short flight from the home of AIR's plan nearest ``origin``:
    300 m east of home, 100 m north (the short plans fly there, see ``write_short_plan``)."""
    lat0, lon0 = (float(v) for v in origin.split(","))
    homes = []
    for plan in sorted((REPO / "missions").glob("*.plan")):
        home = load_mission(plan).planned_home
        assert home is not None
        homes.append((abs(home.lat_deg - lat0) + abs(home.lon_deg - lon0), home))
    home = min(homes, key=lambda item: item[0])[1]
    lat, lon, _ = ned2geodetic(100.0, 300.0, 0.0, home.lat_deg, home.lon_deg, 0.0)
    return f"{lat:.6f},{lon:.6f}"


def one_run_spec(spec_path: Path, folder: Path) -> Path:
    """A SPEC of examples/ cut to one run of 45 simulated seconds."""
    spec = yaml.safe_load(spec_path.read_text(encoding="utf-8"))
    spec["axes"] = {key: values[:1] for key, values in (spec.get("axes") or {}).items()}
    spec.setdefault("base", {})["max-sim-time"] = 45
    path = folder / f"docs_{spec_path.name}"
    path.write_text(yaml.safe_dump(spec), encoding="utf-8")
    return path


def as_run(argv: list[str], folder: Path, endpoint: str) -> list[str]:
    """The command the test runs for one line (see the module docstring)."""
    if argv[0] == "python":  # a bus client of bridges/: on the test's bus, patient
        args = [*argv[1:], "--wait", "120"] if "--wait" not in argv else argv[1:]
        if "--zenoh-connect" not in args:
            args += ["--zenoh-connect", endpoint]
        return [sys.executable, *args]
    args = argv[1:]
    if args[0] == "fly" and "--altitude-offset" in args and "--air-start" not in args:
        args.append("--air-start")  # a climb of 800 m takes minutes of simulation
    if args[0] == "fly" and "--wait-for" in args and "--air-start" not in args:
        args.append("--air-start")  # its localizer answers every frame of the climb too
    if "--scenarios" in args and args[args.index("--scenarios") + 1] in ("all", "air"):
        args[args.index("--scenarios") + 1] = "UC-200"
    if (
        args[0] in ("dataset", "bench", "sweep")
        and args[1] != "report"
        and "--missions" not in args
    ):
        args += ["--missions", "missions"]  # the short plans (else the checkout's own)
    if args[:2] == ["map", "make"] and "--gsd-m" not in args:
        args += ["--gsd-m", "2.5"]
    if args[:2] == ["map", "make"] and "--size-m" in args and "--origin" in args:
        at = args.index("--origin") + 1
        args[at] = short_flight_area(args[at])
        size = args.index("--size-m") + 1
        args[size : size + 2] = [str(SHORT_WINDOW_M), str(SHORT_WINDOW_M)]
    if args[0] == "sweep" and args[1].startswith("examples/"):
        args[1] = str(one_run_spec(folder / args[1], folder))
    if args[0] == "serve":
        links = [i for i, a in enumerate(args) if a == "--mavlink"]
        for i in links:
            args[i + 1] = (
                "tcpin:127.0.0.1:0" if args[i + 1].startswith("tcpin") else "udpin:127.0.0.1:0"
            )
        if not links:
            args += ["--mavlink", "udpin:127.0.0.1:0"]
        args += ["--max-sim-time", "5", "--no-video"]
    if "--wait-for" in args and "--wait-timeout" not in args:
        args += ["--wait-timeout", "120"]  # its partner starts after it, on a loaded machine
    serves = args[0] in ("fly", "serve", "router")
    return [sys.executable, "-m", "air_sitl", *bus_endpoint(args, endpoint, serves=serves)]


def bus_endpoint(args: list[str], endpoint: str, *, serves: bool) -> list[str]:
    """The bus on ``endpoint`` instead of the default 7447: who serves listens there, the
    others connect to it."""
    implies = ("--zenoh", "--bus", "--wait-for", "--nav-aid")  # each puts the line on the bus
    uses_bus = any(a.startswith(implies) for a in args)
    if not uses_bus or "--zenoh-listen" in args or "--zenoh-connect" in args:
        return args
    return [*args, "--zenoh-listen" if serves else "--zenoh-connect", endpoint]


def run_block(block: list[str], folder: Path, endpoint: str, where: str) -> float:
    """Run one block's lines; the wall seconds it took."""
    start = time.monotonic()
    background: list[tuple[str, subprocess.Popen[str]]] = []
    try:
        for line in block:
            argv = shlex.split(line, comments=True)
            if not argv or argv[0] not in ("air-sitl", "python"):
                continue  # pip, ray, docker: not ours to run here
            if argv[0] == "python" and not argv[1].startswith("bridges/"):
                continue
            behind = argv[-1] == "&"
            env = {**os.environ, "PYTHONPATH": str(REPO)}  # this checkout's air_sitl
            cmd = as_run(argv[:-1] if behind else argv, folder, endpoint)
            if behind:
                proc = subprocess.Popen(
                    cmd,
                    cwd=folder,
                    env=env,
                    stdout=subprocess.PIPE,
                    stderr=subprocess.PIPE,
                    text=True,
                )
                background.append((line, proc))
                continue
            run = subprocess.run(
                cmd,
                cwd=folder,
                env=env,
                capture_output=True,
                text=True,
                timeout=LINE_TIMEOUT_S,
                check=False,
            )
            said = f"{where}: {line}\n{run.stdout[-1500:]}\n{run.stderr[-1500:]}"
            assert run.returncode == 0, said
            assert OFF_MAP not in run.stderr, said
        for line, proc in background:
            out, err = proc.communicate(timeout=LINE_TIMEOUT_S)
            said = f"{where}: {line}\n{out[-1500:]}\n{err[-1500:]}"
            assert proc.returncode == 0, said
            assert OFF_MAP not in err, said
    finally:
        for _, proc in background:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
    return time.monotonic() - start


def test_every_sh_block_runs_in_order_in_one_folder(tmp_path: Path) -> None:
    from ports import free_port

    for name in ("examples", "bridges"):
        (tmp_path / name).symlink_to(REPO / name)
    short_missions(tmp_path / "missions")
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    costs = {}
    for page in pages():
        if page.name in ONLINE_PAGES:
            continue
        for k, block in enumerate(sh_blocks(page)):
            costs[f"{page.name}#{k}"] = run_block(block, tmp_path, endpoint, page.name)
    print(json.dumps({k: round(v, 1) for k, v in costs.items()}, indent=1))
    # What Getting started (README's tour) says its lines write.
    out = tmp_path / "out"
    made = [
        "uc200/manifest.json", "uc200-bag/metadata.yaml", "uc200/estimates/mapmatch.csv",
        "fl200-wind/summary.json", "urban-2009.tif", "urban-2016.tif", "uc200-tif/manifest.json",
        "frame.jpg", "air/UC-200.zip", "air/FC-200.zip", "bench/leaderboard.md",
        "bench/date2/leaderboard.md", "sweep/results.jsonl", "sweep/report.md",
    ]  # fmt: skip
    missing = [name for name in made if not (out / name).exists()]
    assert not missing, missing
    assert list((out / "plots").glob("*.png"))
