"""The context-manager shape shared by everything that holds a resource until ``close()``."""

from __future__ import annotations

from types import TracebackType
from typing import Self


class Closeable:
    """Base of a resource closed by ``close()``; ``with`` closes it whatever happens."""

    def close(self) -> None:
        """Release the resource (idempotent in every subclass)."""

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
