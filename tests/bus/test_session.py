"""Real zenoh sessions on loopback: publish, subscribe, query, configuration, access control."""

from __future__ import annotations

from pathlib import Path

import pytest

from air_sitl.bus.keys import KeySpace
from air_sitl.bus.publisher import BusPublisher, PublishOptions
from air_sitl.bus.session import BusConfig, Message, QueryAnswer, QueryRequest, open_bus
from air_sitl.errors import BusError

from .helpers import free_endpoint, make_sample, pair, wait_until


def test_publish_subscribe_with_attachment_and_query() -> None:
    a, b = pair(free_endpoint())
    with a, b:
        got: list[Message] = []
        b.subscribe("air/t/**", got.append)

        def answer(request: QueryRequest) -> QueryAnswer:
            if request.payload == b"boom":
                raise BusError("bad request")
            return QueryAnswer(request.payload[::-1], b"meta")

        a.queryable("air/t/q", answer)
        pub = a.publisher("air/t/imu", encoding="application/json")
        assert wait_until(lambda: pub.matched)
        pub.put(b"hello", b"att")
        assert wait_until(lambda: len(got) == 1)
        assert got[0] == Message("air/t/imu", b"hello", b"att")
        reply = b.query("air/t/q", b"abc")
        assert (reply.payload, reply.attachment) == (b"cba", b"meta")
        with pytest.raises(BusError, match="bad request"):
            b.query("air/t/q", b"boom")
        with pytest.raises(BusError, match="no answer"):
            b.query("air/t/nobody", b"", timeout_s=0.5)
        assert a.peers() and b.peers()


def test_a_port_in_use_is_a_one_line_error() -> None:
    endpoint = free_endpoint()
    with (
        open_bus(BusConfig(listen=(endpoint,), connect=(), serves=True)),
        pytest.raises(BusError) as info,
    ):
        open_bus(BusConfig(listen=(endpoint,), connect=(), serves=True))
    assert endpoint in str(info.value) and "\n" not in str(info.value)
    assert "Address already in use" in str(info.value) and ".rs:" not in str(info.value)


def test_a_broken_config_file_names_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "zenoh.json5"
    bad.write_text("{ mode: ", encoding="utf-8")
    with pytest.raises(BusError, match=r"zenoh\.json5: not a usable zenoh JSON5 config"):
        open_bus(BusConfig(config_file=bad))


DENY_TRUTH = """{
  mode: "peer",
  scouting: { multicast: { enabled: false } },
  access_control: {
    enabled: true,
    default_permission: "allow",
    rules: [{ id: "no-truth", permission: "deny", flows: ["egress", "ingress"],
              messages: ["put", "delete", "declare_subscriber", "query", "reply"],
              key_exprs: ["air/**/truth"] }],
    subjects: [{ id: "anyone" }],
    policies: [{ rules: ["no-truth"], subjects: ["anyone"] }],
  },
}
"""


@pytest.mark.parametrize("deny", [False, True])
def test_access_control_config_keeps_truth_from_subscribers(tmp_path: Path, deny: bool) -> None:
    endpoint = free_endpoint()
    config = None
    if deny:
        config = tmp_path / "deny-truth.json5"
        config.write_text(DENY_TRUTH, encoding="utf-8")
    sim = open_bus(BusConfig(listen=(endpoint,), connect=(), config_file=config, serves=True))
    client = open_bus(BusConfig(listen=(), connect=(endpoint,)))
    with sim, client:
        got: dict[str, int] = {}

        def count(m: Message) -> None:
            got[m.key] = got.get(m.key, 0) + 1

        client.subscribe("air/**", count)
        keys = KeySpace()
        publisher = BusPublisher(sim, PublishOptions(keys=keys, publish_truth=True))
        assert wait_until(lambda: publisher._clock.matched)
        for step in range(50):
            publisher.on_sample(make_sample(step * 5_000_000))
        assert wait_until(lambda: got.get(keys.imu, 0) == 50)
        if deny:
            # One step more: its IMU sample is put after every truth sample of the 50 steps, on
            # the same link; once it arrived, any truth sample let through would have too.
            publisher.on_sample(make_sample(50 * 5_000_000))
            assert wait_until(lambda: got.get(keys.imu, 0) == 51)
            assert got.get(keys.truth, 0) == 0
        else:
            assert wait_until(lambda: got.get(keys.truth, 0) == 50)
        if deny:
            with pytest.raises(BusError):
                client.query(keys.truth, timeout_s=0.5)
        else:
            assert client.query(keys.truth).payload
