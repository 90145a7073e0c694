"""``air-sitl render`` and ``air-sitl map make`` as a user runs them: files, exit codes."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from georef_helpers import HOME

from air_sitl.cli import main


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "air_sitl", *args],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def test_render_writes_a_jpeg(tmp_path: Path) -> None:
    out = tmp_path / "f.jpg"
    r = _cli(
        *f"render --map forest --lat {HOME.lat_deg} --lon {HOME.lon_deg} --alt-agl 300".split(),
        *("--roll", "10", "--yaw", "45", "--out", str(out)),
    )
    assert r.returncode == 0, r.stderr
    img = cv2.imdecode(np.frombuffer(out.read_bytes(), np.uint8), cv2.IMREAD_COLOR)
    assert img is not None and img.shape == (480, 640, 3)
    assert "centre at map px" in r.stdout


@pytest.mark.integration
def test_map_make_then_render_it(tmp_path: Path) -> None:
    # 300 x 240 m: the frame at 200 m (217 x 163 m) with 40 m to spare on each side.
    tif = tmp_path / "m.tif"
    r = _cli(
        *("map", "make", "forest", "--out", str(tif), "--size-m", "300", "240"),
        *("--origin", f"{HOME.lat_deg},{HOME.lon_deg}", "--date", "2"),
    )
    assert r.returncode == 0, r.stderr
    out = tmp_path / "f.png"
    r = _cli(
        *("render", "--map", str(tif), "--lat", str(HOME.lat_deg), "--lon", str(HOME.lon_deg)),
        *("--alt-agl", "200", "--out", str(out), "--noise-sigma", "0"),
    )
    assert r.returncode == 0, r.stderr
    assert "off the map" not in r.stderr, r.stderr  # the whole frame shows the map made
    img = cv2.imread(str(out))
    assert img is not None and img.shape == (480, 640, 3)


# Every case renders at one place into {d}/x.jpg unless it says otherwise ({d}: tmp_path).
_RENDER = "render --lat 54.6 --lon 25.2 --alt-agl 300 --out {d}/x.jpg "


@pytest.mark.parametrize(
    "command",
    [
        _RENDER + "--map suburb",
        _RENDER + "--map {d}/missing.tif",
        _RENDER + "--map {d}/notes.tif",
        "render --lat 54.6 --lon 25.2 --alt-agl -3 --out {d}/x.jpg",
        "render --lat 54.6 --lon 25.2 --alt-agl 300 --out {d}/x.gif",
        _RENDER + "--map-date 7",
        _RENDER + "--camera-mount-rpy-deg 1,2",
        _RENDER + "--jpeg-quality 0",
        "map make urban --out {d}/nofolder/m.tif",
        "map make urban --out {d}/m.png",
        "map make urban --out {d}/m.tif --origin north",
        "map make urban --out {d}/m.tif --size-m 0 100",
        "map make urban --out {d}/m.tif --gsd-m -1",
        "map make urban --out {d}/m.tif --date winter",
    ],
)
def test_bad_input_exits_2_with_one_line(
    tmp_path: Path, command: str, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "notes.tif").write_text("not a tiff")
    code = main(command.format(d=tmp_path).split())
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("air-sitl: error: "), err
    assert not (tmp_path / "x.jpg").exists()


@pytest.mark.parametrize(
    "args",
    [
        ["render", "--map", "{d}/plain.tif", "--lat", "54.6", "--lon", "25.2", "--alt-agl", "300",
         "--out", "{d}/x.jpg"],
        ["map", "make", "forest", "--out", "{d}/m.tif", "--origin", "91,0"],
    ],
)  # fmt: skip
def test_bad_input_exit_code_of_the_real_command(tmp_path: Path, args: list[str]) -> None:
    (tmp_path / "plain.tif").write_bytes(b"II*\x00" + bytes(64))
    r = _cli(*[a.format(d=tmp_path) for a in args])
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("air-sitl: error: "), r.stderr
