"""The parameter protocol: PARAM_REQUEST_LIST, PARAM_REQUEST_READ and PARAM_SET answered with
PARAM_VALUE; integers travel bytewise in the float field (PARAM_ENCODE_BYTEWISE capability).

As PX4 (mavlink_parameters.cpp): a set stores the value as sent, with no range check, and is
answered with PARAM_VALUE to every client; an unknown name or index gets no PARAM_VALUE but an
informational STATUSTEXT "[pm] unknown param: NAME" ("[pm] unknown param ID: N"); PX4 sends no
PARAM_ERROR (a newer message of the development dialect), and neither do we.
"""

from __future__ import annotations

import struct
from typing import Any

from air_sitl.errors import AirSitlError
from air_sitl.mavlink.codec import Message, mav
from air_sitl.mavlink.interfaces import (
    SEVERITY_INFO,
    SEVERITY_WARNING,
    AutopilotLike,
    EndpointPart,
    Handler,
)
from air_sitl.mavlink.links import Channel


def param_name(raw: Any) -> str:
    """A PARAM_* ``param_id`` as text (16 characters, NUL-padded when shorter)."""
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", errors="replace")
    return str(raw).rstrip("\x00")


class ParamProtocol(EndpointPart):
    """Serves the endpoint's parameter store."""

    def handlers(self) -> dict[str, Handler]:
        return {
            "PARAM_REQUEST_LIST": self.on_request_list,
            "PARAM_REQUEST_READ": self.on_request_read,
            "PARAM_SET": self.on_set,
        }

    def value_message(self, name: str) -> Message | None:
        """PARAM_VALUE of ``name``."""
        params = self._ep.params
        if params is None:
            return None
        names = params.names()
        value = params.get(name)
        if getattr(params.spec(name), "is_int", False):
            packed = struct.unpack("<f", struct.pack("<i", round(value)))[0]
            return mav.MAVLink_param_value_message(
                name.encode("ascii"),
                packed,
                mav.MAV_PARAM_TYPE_INT32,
                len(names),
                names.index(name),
            )
        return mav.MAVLink_param_value_message(
            name.encode("ascii"), value, mav.MAV_PARAM_TYPE_REAL32, len(names), names.index(name)
        )

    def on_request_list(self, ch: Channel, msg: Message) -> None:
        """Every parameter, in index order."""
        params = self._ep.params
        if params is None:
            return
        for name in params.names():
            value = self.value_message(name)
            if value is not None:
                self._ep.reply(ch, value)

    def on_request_read(self, ch: Channel, msg: Message) -> None:
        """One parameter by index, or by name when the index is -1."""
        params = self._ep.params
        if params is None:
            return
        names = params.names()
        if msg.param_index >= 0:
            if msg.param_index >= len(names):
                self._ep.reply_text(ch, SEVERITY_INFO, f"[pm] unknown param ID: {msg.param_index}")
                return
            name = names[msg.param_index]
        else:
            name = param_name(msg.param_id)
            if name not in names:
                self._ep.reply_text(ch, SEVERITY_INFO, f"[pm] unknown param: {name}")
                return
        value = self.value_message(name)
        if value is not None:
            self._ep.reply(ch, value)

    def on_set(self, ch: Channel, msg: Message) -> None:
        """Set on the simulation thread, then PARAM_VALUE to every client."""
        ep = self._ep
        params = ep.params
        if params is None:
            return
        name = param_name(msg.param_id)
        if name not in params.names():
            ep.reply_text(ch, SEVERITY_INFO, f"[pm] unknown param: {name}")
            return
        value = float(msg.param_value)
        if msg.param_type in (mav.MAV_PARAM_TYPE_INT32, mav.MAV_PARAM_TYPE_UINT32):
            value = float(struct.unpack("<i", struct.pack("<f", msg.param_value))[0])

        def job(_ap: AutopilotLike) -> None:
            try:
                params.set(name, value)
                problem = ""
            except AirSitlError as err:
                problem = str(err)

            def answer() -> None:
                if problem:
                    ep.broadcast_text(SEVERITY_WARNING, problem)
                reply = self.value_message(name)
                if reply is not None:
                    ep.broadcast(reply)

            ep.to_io(answer)

        ep.on_sim(job)
