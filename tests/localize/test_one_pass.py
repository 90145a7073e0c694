"""Several methods in one pass over an archive (issue 34): each method's estimates are the
bytes of its run alone, on a date the matcher fixes and on a hard gap where it refuses and
its search window grows; a frame is decoded once for all the methods fed it."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from short_plans import write_short_plan

from air_sitl.cli import main
from air_sitl.localize.archive import run_archive, run_archive_methods
from air_sitl.localize.decode import decode_gray
from air_sitl.maps import open_map
from air_sitl.maps.base import MapSource
from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=38.5125, lon_deg=-121.4935, alt_amsl_m=10.0)
METHODS = ("mapmatch", "vo", "deadreckon")


def _fly(folder: Path, kind: str, date: int) -> Path:
    """A 40 m capture leg (about 100 frames) over ``kind`` at ``date``."""
    plan = write_short_plan(folder / "short.plan", HOME, leg_m=40.0)
    out = folder / f"{kind}-{date}"
    argv = ["fly", str(plan), "--air-start", "--map", kind, "--map-date", str(date)]
    assert main([*argv, "--seed", "3", "--quiet", "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def flights(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Urban over date 0 (the reference's own date: fixes) and farmland over date 2 against
    date 0 (a hard gap: matches refused, the search radius growing)."""
    folder = tmp_path_factory.mktemp("one-pass")
    return {"same date": _fly(folder, "urban", 0), "hard gap": _fly(folder, "farmland", 2)}


def _fixes(path: Path) -> list[str]:
    with path.open(encoding="utf-8", newline="") as f:
        return [row["fix"] for row in csv.DictReader(f)]


@pytest.mark.parametrize("case", ["same date", "hard gap"])
def test_one_pass_gives_each_method_the_bytes_of_its_run_alone(
    flights: dict[str, Path], case: str
) -> None:
    archive = flights[case]
    kept: dict[tuple[object, ...], MapSource] = {}

    def reference(spec: str, home: GeoPoint, **kw: Any) -> MapSource:  # drawn once here
        key = (spec, home, *sorted(kw.items()))
        return kept[key] if key in kept else kept.setdefault(key, open_map(spec, home, **kw))

    alone = {
        m: run_archive(
            archive, m, name=f"{m}-alone", reference_date=0, seed=1, open_map=reference
        ).path.read_bytes()
        for m in METHODS
    }
    runs = run_archive_methods(
        archive,
        [(m, f"{m}-pass", {}) for m in METHODS],
        reference_date=0,
        seed=1,
        open_map=reference,
    )
    assert len(kept) == 1
    assert [r.name for r in runs] == [f"{m}-pass" for m in METHODS]
    for method, run in zip(METHODS, runs, strict=True):
        assert run.path.read_bytes() == alone[method], f"{case}: {method} differs"
        assert run.frames > 80 and run.wall_s > 0
    fixes = _fixes(runs[0].path)
    if case == "same date":
        assert fixes.count("1") > 0.9 * len(fixes)
    else:  # the hard path: refusals (the window grown) in most frames
        assert fixes.count("0") > 0.5 * len(fixes)


def test_a_frame_is_decoded_once_for_every_method_fed_it(flights: dict[str, Path]) -> None:
    jpegs = sorted(flights["same date"].glob("*.jpg"))[:2]
    first, second = (p.read_bytes() for p in jpegs)
    image = decode_gray(first, 2)
    assert decode_gray(first, 2) is image  # the same bytes object, the same reduction
    assert not image.flags.writeable  # no method can spoil it for the next
    assert decode_gray(first, 1).shape == (2 * image.shape[0], 2 * image.shape[1])
    copy = bytes(bytearray(first))  # equal bytes, another object: decoded again, equal
    again = decode_gray(copy, 2)
    assert again is not image and np.array_equal(again, image)
    assert not np.array_equal(decode_gray(second, 2), image)
    with pytest.raises(ValueError, match="not a decodable JPEG"):
        decode_gray(b"not a jpeg", 2)
