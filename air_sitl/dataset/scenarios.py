"""The scenarios: AIR's 12 (the paper's Table 2) and our 6 over farmland, where their plans
live, the stats table.

``--scenarios all`` is all 18: AIR's 12 and the farmland ones; ``air`` names AIR's 12 alone,
``farmland`` the 6 farmland ones (groups and names mix in a comma list). The stats table
compares only AIR's rows with the paper: its ``total`` row sums AIR's rows (as when AIR's 12
alone are flown), the farmland rows follow with their own ``total farmland`` row and no paper
figures (the paper has no farmland).
"""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import air_sitl
from air_sitl.errors import OptionError

# Table 2 of the AIR paper (SPEC section 1): images at 50 Hz, flown distance in metres.
PAPER_TABLE: dict[str, tuple[int, int]] = {
    "FL-200": (11837, 2936),
    "FL-300": (9020, 2736),
    "FR-200": (16056, 4748),
    "FR-300": (15307, 4541),
    "FC-200": (3601, 1065),
    "FC-300": (3450, 1028),
    "UL-200": (8735, 2592),
    "UL-300": (8416, 2496),
    "UR-200": (14997, 4418),
    "UR-300": (15361, 4542),
    "UC-200": (3422, 1016),
    "UC-300": (3272, 970),
}
AIR_SCENARIOS: tuple[str, ...] = tuple(PAPER_TABLE)
# Ours: AIR's shapes and heights (map letter A, agricultural) over the ``farmland`` map, each
# with the figures (images at 50 Hz, captured distance) of its urban counterpart.
FARMLAND_TABLE: dict[str, tuple[int, int]] = {
    "A" + name[1:]: figures for name, figures in PAPER_TABLE.items() if name[0] == "U"
}
FARMLAND_SCENARIOS: tuple[str, ...] = tuple(FARMLAND_TABLE)
SCENARIO_TABLE: dict[str, tuple[int, int]] = {**PAPER_TABLE, **FARMLAND_TABLE}  # planned
ALL_SCENARIOS: tuple[str, ...] = AIR_SCENARIOS + FARMLAND_SCENARIOS
GROUPS: dict[str, tuple[str, ...]] = {
    "all": ALL_SCENARIOS,
    "air": AIR_SCENARIOS,
    "farmland": FARMLAND_SCENARIOS,
}

STATS_COLUMNS = (
    "scenario",
    "images",
    "distance_m",
    "paper_images",
    "paper_distance_m",
    "images_ratio",
    "distance_ratio",
    "mission_completed",
    "sim_time_s",
)


def missions_dir(explicit: str | None = None) -> Path:
    """The folder holding ``<scenario>.plan``: ``--missions``, the repository's, or ./missions."""
    if explicit:
        path = Path(explicit)
        if not path.is_dir():
            msg = f"--missions {explicit}: no such folder"
            raise OptionError(msg)
        return path
    candidates = [
        Path(air_sitl.__file__).resolve().parent.parent / "missions",  # editable install
        Path.cwd() / "missions",
    ]
    for path in candidates:
        if path.is_dir() and any(path.glob("*.plan")):
            return path
    looked = ", ".join(str(p) for p in candidates)
    msg = f"no missions folder with .plan files found (looked in {looked}); pass --missions DIR"
    raise OptionError(msg)


def parse_scenarios(text: str, folder: Path) -> list[str]:
    """A comma list of names and groups (``all``, ``air``, ``farmland``); each name must
    have ``<name>.plan`` in ``folder``."""
    names: list[str] = []
    for part in (p.strip() for p in text.split(",")):
        if part.lower() in GROUPS:
            names += GROUPS[part.lower()]
        elif part:
            names.append(part.upper())
    if not names:
        msg = (
            f"--scenarios {text!r}: expected 'all', 'air', 'farmland' or names such as "
            "FL-200,UC-300,AC-200"
        )
        raise OptionError(msg)
    available = sorted(p.stem for p in folder.glob("*.plan"))
    by_upper = {n.upper(): n for n in available}
    out: list[str] = []
    for name in names:
        if name not in by_upper:
            msg = (
                f"--scenarios: {name} has no plan in {folder} "
                f"(available: {', '.join(available) or 'none'})"
            )
            raise OptionError(msg)
        if by_upper[name] not in out:
            out.append(by_upper[name])
    return out


@dataclass(frozen=True, slots=True, kw_only=True)
class ScenarioStats:
    """One line of the AIR table: what we flew beside what the paper reports."""

    scenario: str
    images: int
    distance_m: float
    mission_completed: bool
    sim_time_s: float

    def row(self) -> list[str]:
        """The stats.csv fields."""
        paper = PAPER_TABLE.get(self.scenario.split("@")[0].upper())
        p_img, p_dist = paper if paper else (None, None)
        return [
            self.scenario,
            str(self.images),
            f"{self.distance_m:.1f}",
            "" if p_img is None else str(p_img),
            "" if p_dist is None else str(p_dist),
            "" if not p_img else f"{self.images / p_img:.3f}",
            "" if not p_dist else f"{self.distance_m / p_dist:.3f}",
            str(self.mission_completed).lower(),
            f"{self.sim_time_s:.1f}",
        ]


def expected_images(scenario: str) -> int:
    """The planned frames of a scenario (``FL-200`` or ``FL-200@1``; 0 when unknown)."""
    return SCENARIO_TABLE.get(scenario.split("@", maxsplit=1)[0].upper(), (0, 0))[0]


def read_stats(path: Path) -> list[ScenarioStats]:
    """The scenario rows of an earlier ``stats.csv`` (the total left out); none when absent or
    unreadable (the table is then made of this run's rows alone)."""
    try:
        text = path.read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError):
        return []
    rows = list(csv.DictReader(io.StringIO(text)))
    out = []
    for row in rows:
        try:
            if row["scenario"].startswith("total"):
                continue
            out.append(
                ScenarioStats(
                    scenario=row["scenario"],
                    images=int(row["images"]),
                    distance_m=float(row["distance_m"]),
                    mission_completed=row["mission_completed"] == "true",
                    sim_time_s=float(row["sim_time_s"]),
                )
            )
        except (KeyError, TypeError, ValueError):
            return []
    return out


def stats_table(stats: Sequence[ScenarioStats]) -> list[list[str]]:
    """Rows for stats.csv: the header, AIR's scenarios and their ``total`` beside the paper's
    figures, then any other scenarios (farmland) and their ``total farmland``."""
    air = [s for s in stats if s.scenario.split("@")[0].upper() in PAPER_TABLE]
    other = [s for s in stats if s not in air]
    rows = [list(STATS_COLUMNS)]
    if air:
        rows += [s.row() for s in air]
        rows.append(_total("total", air))
    if other:
        rows += [s.row() for s in other]
        rows.append(_total("total farmland", other))
    return rows


def _total(label: str, stats: Sequence[ScenarioStats]) -> list[str]:
    """The total row of ``stats`` (with the paper's figures when it has them all)."""
    images = sum(s.images for s in stats)
    # Totals of the rows as written (to 0.1): the same whether a row was flown now or read
    # back from an earlier stats.csv.
    dist = sum(round(s.distance_m, 1) for s in stats)
    papers = [PAPER_TABLE.get(s.scenario.split("@")[0].upper()) for s in stats]
    known = [p for p in papers if p is not None]
    p_img = sum(p[0] for p in known) if len(known) == len(stats) else None
    p_dist = sum(p[1] for p in known) if len(known) == len(stats) else None
    return [
        label,
        str(images),
        f"{dist:.1f}",
        "" if p_img is None else str(p_img),
        "" if p_dist is None else str(p_dist),
        "" if not p_img else f"{images / p_img:.3f}",
        "" if not p_dist else f"{dist / p_dist:.3f}",
        str(all(s.mission_completed for s in stats)).lower(),
        f"{sum(round(s.sim_time_s, 1) for s in stats):.1f}",
    ]


def format_table(rows: Sequence[Sequence[str]]) -> str:
    """The stats table as aligned text for the terminal."""
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in rows)
