"""Kernels built ahead of time (``air_sitl.compiled``): the bytes of numba's JIT, without numba.

A fresh process flies 10 s on the onboard filter and 5 s cruising from an air start, renders
a frame over relief, and one with every camera effect, hashing each; with the built kernels
it never imports numba, and it gives the same hashes as a process where numba's JIT compiles
them (forced, or because no cache is writable: no error then, nothing on stderr). Two
processes that find no build start at once: one builds (and says so on its terminal), both
run on that build, and nothing half-written is left.
"""

from __future__ import annotations

import os
import pty
import shutil
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from air_sitl import compiled, compiled_build

REPO = Path(__file__).resolve().parent.parent

pytestmark = pytest.mark.integration

FLY_AND_RENDER = """
import hashlib, math, sys
from dataclasses import replace
from air_sitl.builder import build_flight, load_setup
from air_sitl.camera.effects import CameraEffects
from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.maps.open import open_map, open_surface
from air_sitl.options import FlightOptions
from air_sitl.state import GeoPoint

flight = build_flight(load_setup("missions/FR-300.plan", FlightOptions(nav="ekf")))
h = hashlib.sha256()
for _ in range(2000):  # 10 simulated seconds: prediction, GNSS, baro, compass, airspeed
    h.update(repr(flight.step()).encode())
print("flight", h.hexdigest())
air = FlightOptions(nav="truth", air_start=True)
cruise = build_flight(load_setup("missions/UC-200.plan", air))
h = hashlib.sha256()
for _ in range(1000):  # the controller's cruise law, the flight loop's kernels (group flight)
    h.update(repr(cruise.step()).encode())
print("cruise", h.hexdigest())
home = GeoPoint(lat_deg=47.3769, lon_deg=8.5417, alt_amsl_m=408.0)
m = open_map("urban", home, seed=3)
s = pose_state(home.lat_deg, home.lon_deg, home.alt_amsl_m + 180.0, alt_agl_m=180.0,
               roll_rad=0.2, pitch_rad=0.05, yaw_rad=1.0)
s = replace(s, rate_frd_rad_s=(math.radians(45.0), 0.0, 0.0))
every = CameraEffects(enabled=("blur", "rolling-shutter", "vignette", "exposure", "haze",
                               "distortion"))
for name, camera in (("relief", CameraModel()), ("effects", CameraModel(effects=every))):
    r = Renderer(m, camera, seed=3, surface=open_surface("builtin", m))
    print(name, hashlib.sha256(r.render(s, noise_index=0).tobytes()).hexdigest())
print("numba", "numba" in sys.modules)
"""


def _run(script: str, **env: str) -> tuple[dict[str, str], str]:
    """``script``'s printed lines as {first word: rest}, and its stderr."""
    run = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=600,
        check=False, cwd=REPO, env={**os.environ, "PYTHONPATH": str(REPO), **env},
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    return dict(line.split(" ", 1) for line in run.stdout.splitlines()), run.stderr


def test_built_kernels_give_the_bytes_of_numbas_jit_without_importing_numba() -> None:
    for group in compiled.GROUPS:  # built here if they are not yet
        assert compiled.machine_code(group) is not None, f"{group}: no build could be made"
    built, _ = _run(FLY_AND_RENDER)
    assert built.pop("numba") == "False"
    jit, _ = _run(FLY_AND_RENDER, AIR_SITL_JIT="1")
    assert jit.pop("numba") == "True"  # the check sees numba where it is imported
    assert jit == built


LOAD_EFFECTS = """
import sys
import numpy as np
from air_sitl import compiled
from air_sitl.camera import effects_pixels_kernel
ones, keep_at = np.ones((2, 2), np.float32), np.array([[0, 1, 1, 0], [0, 1, 0, 1]], np.float32)
total = effects_pixels_kernel.light_total(np.full((2, 2, 4), 10, np.uint8), ones, keep_at,
                                          ones, np.zeros(3))
print("total", total)
print("built", compiled.machine_code("effects") is not None, "numba" in sys.modules)
"""


@pytest.mark.parametrize("where", ["no writable cache", "no C compiler", "a failed build"])
def test_where_no_build_can_be_made_numbas_jit_compiles_them_silently(
    where: str, tmp_path: Path
) -> None:
    """No cache directory can be made, no C compiler is on the PATH, or the build failed
    before (noted beside it: not tried again): numba's JIT compiles the kernels in the
    process, with no error and nothing on stderr."""
    cache = tmp_path / "cache"
    cache.mkdir()
    env = {"AIR_SITL_CACHE_DIR": str(cache)}
    if where == "no writable cache":
        (tmp_path / "a-file").write_text("")
        env["AIR_SITL_CACHE_DIR"] = str(tmp_path / "a-file" / "cache")
    elif where == "no C compiler":
        env["PATH"] = str(tmp_path)
    else:
        name = compiled_build.build_name("effects", compiled.GROUPS["effects"].modules)
        (cache / name).with_suffix(".failed").write_text("a compiler's error")
    out, err = _run(LOAD_EFFECTS, **env)
    assert out == {"total": "120.0", "built": "False True"} and err == ""
    assert not list(cache.glob("*.so"))


def _read_all(fd: int, into: list[bytes]) -> None:
    """What a pty's other side writes, until it is closed."""
    while True:
        try:
            chunk = os.read(fd, 4096)
        except OSError:
            break
        if not chunk:
            break
        into.append(chunk)
    os.close(fd)


LOAD_FLIGHT = """
import sys
import numpy as np
from air_sitl import battery_kernel, compiled
pack = np.array([5000.0, 4.0, 4.2, 3.3, 0.05, 2.0, 3.0])
print("volts", battery_kernel.step(pack, 0.0, 0.0, 0.005, 0.5)[0])
print("built", compiled.machine_code("flight") is not None, "numba" in sys.modules)
"""


def test_processes_starting_at_once_share_one_build(tmp_path: Path) -> None:
    """Two processes on terminals find no build and start together (xdist workers, a pool):
    one builds it and says so, the other waits on the lock and says nothing; both load the
    one build, and nothing half-written is left. The cheapest group to build (``flight``:
    about 8 s of CPU against 17-33 s for the others)."""
    cache = tmp_path / "cache"
    cache.mkdir()
    for kept in compiled_build.cache_dirs()[0].glob("_air_sitl_mixins-*"):
        shutil.copytree(kept, cache / kept.name)  # pycc's C runtime: only the kernels to build
    env = {**os.environ, "PYTHONPATH": str(REPO), "AIR_SITL_CACHE_DIR": str(cache)}
    runs, said, readers = [], [], []
    for _ in range(2):
        main, sub = pty.openpty()
        runs.append(subprocess.Popen(
            [sys.executable, "-c", LOAD_FLIGHT], stdout=subprocess.PIPE, stderr=sub,
            text=True, cwd=REPO, env=env,
        ))  # fmt: skip
        os.close(sub)
        said.append([])
        readers.append(threading.Thread(target=_read_all, args=(main, said[-1])))
        readers[-1].start()
    outputs = [run.communicate(timeout=600)[0] for run in runs]
    for reader in readers:
        reader.join(timeout=60)
    volts = set()
    for run, out in zip(runs, outputs, strict=True):
        assert run.returncode == 0, said
        lines = out.splitlines()
        assert lines[1:] == ["built True False"], out
        volts.add(lines[0])
    assert len(volts) == 1, volts
    notices = [b"".join(s).decode().count("compiling the flight loop") for s in said]
    assert sorted(notices) == [0, 1], said
    left = {p.name for p in cache.iterdir() if not p.name.startswith("_air_sitl_mixins")}
    name = compiled_build.build_name("flight", compiled.GROUPS["flight"].modules)
    assert left == {"_air_sitl_flight.lock", name}  # no temporary file, no failure note


def test_a_built_kernel_refuses_an_argument_its_signature_does_not_take() -> None:
    """The tests run every built kernel checked (``AIR_SITL_CHECK_KERNELS``, conftest): an
    array of another type or layout, or a scalar of another kind, fails naming the argument,
    where machine code would read it wrongly."""
    import numpy as np

    from air_sitl import battery_kernel

    assert compiled.machine_code("flight") is not None
    pack = np.array([5000.0, 4.0, 4.2, 3.3, 0.05, 2.0, 3.0])
    volts = battery_kernel.step(pack, 0.0, 0.0, 0.005, 0.5)[0]
    assert 16.0 < volts < 16.8
    wrong = {
        "argument 1 is float32 array of rank 1, contiguous": (pack.astype(np.float32), 0.5),
        "argument 1 is float64 array of rank 1, a view": (np.repeat(pack, 2)[::2], 0.5),
        "argument 1 is float64 array of rank 2, contiguous": (pack[None, :], 0.5),
        "argument 5 is str": (pack, "0.5"),
    }
    for said, (array, throttle) in wrong.items():
        with pytest.raises(TypeError, match=said):
            battery_kernel.step(array, 0.0, 0.0, 0.005, throttle)
