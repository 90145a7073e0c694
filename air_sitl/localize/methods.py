"""The registered localization methods: name -> factory(**options) -> Localizer.

The drivers call a factory with no arguments (``METHODS[name]()``) and give everything a flight
provides through :class:`~air_sitl.localize.base.LocalizerContext` in ``reset``; keyword options
are for callers tuning a method. Adding a method is one line here.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from air_sitl.errors import OptionError
from air_sitl.localize.base import Localizer
from air_sitl.localize.deadreckon import DeadReckoning
from air_sitl.localize.fused import FusedLocalizer
from air_sitl.localize.mapmatch import MapMatchLocalizer
from air_sitl.localize.mapmatch_axial import AxialMapMatchLocalizer
from air_sitl.localize.vo import VisualOdometry

# method name -> factory(**options) -> Localizer
METHODS: dict[str, Callable[..., Localizer]] = {
    "deadreckon": DeadReckoning,
    "vo": VisualOdometry,
    "mapmatch": MapMatchLocalizer,
    "mapmatch-axial": AxialMapMatchLocalizer,
    "fused": FusedLocalizer,
}


def make_method(method: str, **options: Any) -> Localizer:
    """The registered method ``method`` (OptionError listing the known ones)."""
    factory = METHODS.get(method)
    if factory is None:
        msg = f"--method {method}: unknown; expected one of {', '.join(sorted(METHODS))}"
        raise OptionError(msg)
    return factory(**options)


def reads_imagery(method: str) -> bool:
    """Whether the registered method ``method`` reads the frames or the map (a method that
    does not declare ``reads_imagery = False`` is taken to read them): one that does not
    gives the same estimates over every map date of one flight (:class:`~air_sitl.localize.
    base.Localizer`)."""
    factory = METHODS.get(method)
    return bool(getattr(factory, "reads_imagery", True))
