"""HTTP for ``map fetch``: requests carrying the user's headers, and signed asset URLs.

Every request of a fetch (the STAC API, the token endpoint, the assets read by GDAL) carries
the ``--header`` / ``--token`` headers given. Planetary Computer keeps its assets in Azure Blob
Storage, readable with a SAS token that its token endpoint hands out per collection:
``GET {endpoint}/{collection}`` answers ``{"msft:expiry": "<RFC 3339>", "token": "<query>"}``
and an asset URL is signed by appending ``?<token>``. A token is reused until a minute before
its expiry (as the ``planetary-computer`` SDK does), then asked again.
"""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from air_sitl.errors import MapError

PC_HOST = "planetarycomputer.microsoft.com"
PC_SAS_ENDPOINT = f"https://{PC_HOST}/api/sas/v1/token"
RENEW_BEFORE_S = 60.0  # a token this close to its expiry is renewed before use
TIMEOUT_S = 60.0
REFUSED = (401, 403)


class HttpError(MapError):
    """A request answered with an HTTP error status (``status``), or not answered (None)."""

    def __init__(self, message: str, status: int | None) -> None:
        super().__init__(message)
        self.status = status


def parse_header(text: str) -> tuple[str, str]:
    """``--header 'Name: value'`` as (name, value)."""
    name, sep, value = text.partition(":")
    if not sep or not name.strip() or any(c in text for c in "\r\n"):
        msg = f"--header {text!r}: expected 'Name: value' (e.g. 'Authorization: Bearer X')"
        raise MapError(msg)
    return (name.strip(), value.strip())


def default_sas_endpoint(stac: str) -> str | None:
    """Planetary Computer's token endpoint for its own STAC API; None for any other source."""
    return PC_SAS_ENDPOINT if urllib.parse.urlparse(stac).hostname == PC_HOST else None


@dataclass(frozen=True, slots=True)
class Http:
    """Requests with the fetch's headers; errors as one line naming ``what`` was asked."""

    headers: tuple[tuple[str, str], ...] = ()

    def json(self, url: str, what: str, body: dict[str, Any] | None = None) -> dict[str, Any]:
        """GET ``url`` (POST ``body`` as JSON when given) and its JSON object."""
        headers = dict(self.headers) | {"Accept": "application/json"}
        data = None
        if body is not None:
            data = json.dumps(body).encode("utf-8")
            headers["Content-Type"] = "application/json"
        request = urllib.request.Request(url, data=data, headers=headers)
        try:
            with urllib.request.urlopen(request, timeout=TIMEOUT_S) as resp:
                raw = resp.read()
        except urllib.error.HTTPError as err:
            hint = " (refused: check --token / --header)" if err.code in REFUSED else ""
            msg = f"{what}: HTTP {err.code} {err.reason}{hint}"
            raise HttpError(msg, err.code) from None
        except (urllib.error.URLError, OSError) as err:
            reason = getattr(err, "reason", err)
            raise HttpError(f"{what}: no answer ({reason})", None) from None
        try:
            value = json.loads(raw)
        except ValueError:
            value = None
        if not isinstance(value, dict):
            raise HttpError(f"{what}: the answer is not a JSON object", None)
        return value

    def status(self, url: str) -> int | None:
        """The HTTP status a one-byte read of ``url`` gets (200 for a 206; None: no answer)."""
        headers = dict(self.headers) | {"Range": "bytes=0-0"}
        try:
            with urllib.request.urlopen(
                urllib.request.Request(url, headers=headers), timeout=TIMEOUT_S
            ):
                return 200
        except urllib.error.HTTPError as err:
            return err.code
        except (urllib.error.URLError, OSError):
            return None

    def gdal_options(self) -> dict[str, str]:
        """GDAL configuration for reading assets over HTTP with these headers."""
        options = {"GDAL_DISABLE_READDIR_ON_OPEN": "EMPTY_DIR"}
        if self.headers:
            options["GDAL_HTTP_HEADERS"] = "\r\n".join(f"{k}: {v}" for k, v in self.headers)
        return options


class SasSigner:
    """Signs asset URLs with the token of their collection from a Planetary Computer-style
    SAS token endpoint; renews a token near its expiry, or when an asset refused it."""

    def __init__(self, endpoint: str, http: Http, clock: Callable[[], float] = time.time) -> None:
        self.endpoint = endpoint.rstrip("/")
        self.http = http
        self.clock = clock
        self._tokens: dict[str, tuple[str, float]] = {}  # collection -> (token, expiry epoch s)
        self.tokens_asked = 0

    def token_url(self, collection: str) -> str:
        """Where the token of ``collection`` is asked."""
        return f"{self.endpoint}/{urllib.parse.quote(collection, safe='')}"

    def sign(self, href: str, collection: str) -> str:
        """``href`` with the collection's token as its query (local paths unchanged)."""
        if urllib.parse.urlparse(href).scheme not in ("http", "https"):
            return href
        token = self._token(collection)
        return f"{href}{'&' if '?' in href else '?'}{token}"

    def renew(self, collection: str) -> None:
        """Forget the collection's token: the next :meth:`sign` asks a new one."""
        self._tokens.pop(collection, None)

    def _token(self, collection: str) -> str:
        cached = self._tokens.get(collection)
        if cached is not None and cached[1] - self.clock() > RENEW_BEFORE_S:
            return cached[0]
        url = self.token_url(collection)
        token, expiry = self._ask(url)
        if expiry <= self.clock():  # expired as it came: ask once more, then say so
            token, expiry = self._ask(url)
            if expiry <= self.clock():
                when = datetime.fromtimestamp(expiry, tz=UTC).isoformat(timespec="seconds")
                msg = (
                    f"--sas-endpoint {url}: the token expired at {when}, also when asked "
                    "again (is this machine's clock right?)"
                )
                raise MapError(msg)
        self._tokens[collection] = (token, expiry)
        return token

    def _ask(self, url: str) -> tuple[str, float]:
        """A token and its expiry (POSIX seconds) from the endpoint."""
        data = self.http.json(url, f"--sas-endpoint {url}")
        self.tokens_asked += 1
        token, expiry = data.get("token"), _epoch(data.get("msft:expiry"))
        if not isinstance(token, str) or not token.lstrip("?") or expiry is None:
            msg = f"--sas-endpoint {url}: expected a JSON object with msft:expiry and token"
            raise MapError(msg)
        return token.lstrip("?"), expiry


def _epoch(text: object) -> float | None:
    """An RFC 3339 time as POSIX seconds (None: not one)."""
    if not isinstance(text, str):
        return None
    try:
        when = datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError:
        return None
    return when.timestamp() if when.tzinfo is not None else None


def unsigned(href: str) -> str:
    """``href`` without its query (what an error line may show: never the token)."""
    return href.split("?", 1)[0]
