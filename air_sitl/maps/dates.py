"""How reports name a map's dates: the acquisition date beside the index (``2 (2016-04-22)``).

A map's ``describe()`` (the manifest's ``map``) holds ``date`` (YYYY-MM-DD of its imagery),
``date_index`` and, for GeoTIFF dates, ``dates`` (every date file's, in index order);
procedural maps' dates are their world's (:func:`air_sitl.maps.procedural.canvas.dates_of`:
``DATES``, the farmland's growing-season ``FARMLAND_DATES``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any


def date_fields(info: Mapping[str, Any]) -> dict[str, Any]:
    """summary.json's ``map`` block of a map's description: date, date_index, dates."""
    if info.get("source") == "procedural":
        from air_sitl.maps.procedural.canvas import dates_of

        dates: list[Any] = [d.label for d in dates_of(info.get("kind"))]
    else:
        dates = list(info.get("dates") or [info.get("date")])
    return {"date": info.get("date"), "date_index": info.get("date_index"), "dates": dates}


def date_name(index: int | None, dates: Sequence[str | None] = ()) -> str:
    """``2 (2016-04-22)``; the index alone when its date is not known."""
    if index is None:
        return "-"
    when = dates[index] if 0 <= index < len(dates) else None
    return f"{index} ({when})" if when else str(index)


def gap_name(reference: int | None, flight: int | None, dates: Sequence[str | None] = ()) -> str:
    """``reference date 0 (2009-06-20) -> flight date 2 (2016-04-22)``."""
    return f"reference date {date_name(reference, dates)} -> flight date {date_name(flight, dates)}"
