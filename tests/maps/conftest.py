"""The maps tests' local STAC API, token endpoint and blob store (``server``)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.maps.stac_server import StacServer, serve_tiles


@pytest.fixture
def server(tmp_path: Path) -> Iterator[StacServer]:
    """Six small COGs (two tiles of three acquisitions) served only with a valid token."""
    with serve_tiles(tmp_path) as srv:
        yield srv
