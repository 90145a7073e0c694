"""docker-compose.yml and the Dockerfile (Docker does not run here): structure, and every
command they run exists in our CLI with those exact arguments."""

from __future__ import annotations

import importlib.util
import re
import shlex
import sys
from typing import Any

import pytest
import yaml

from air_sitl.bus.args import bus_options_from_args
from air_sitl.cli import build_parser
from air_sitl.mavlink.links import parse_link

from .helpers import REPO


def compose() -> dict[str, Any]:
    content = yaml.safe_load((REPO / "docker-compose.yml").read_text())
    assert isinstance(content, dict)
    return content


def localizer_parser() -> Any:
    spec = importlib.util.spec_from_file_location(
        "example_localizer", REPO / "bridges" / "example_localizer.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["example_localizer"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module.build_parser()


def test_services_build_from_this_repository_and_depend_on_defined_services() -> None:
    services = compose()["services"]
    assert {"router", "simulator", "localizer", "ray-head", "ray-worker"} <= set(services)
    for name, service in services.items():
        if "ray" in service.get("profiles", []):  # the Ray nodes: the image with its [ray] extra
            assert service["build"] == {"context": ".", "args": {"EXTRAS": "[ray]"}}, name
            assert service["image"] == "air-sitl:ray", name
        else:
            assert service["build"] == "." and service["image"] == "air-sitl:latest", name
        assert isinstance(service["command"], list) and service["command"], name
        for dep in service.get("depends_on", []):
            assert dep in services, (name, dep)
        for port in service.get("ports", []):
            assert re.fullmatch(r"127\.0\.0\.1:\d+:\d+", port), (name, port)  # host-local only


def test_every_command_parses_with_our_cli() -> None:
    services = compose()["services"]
    parser = build_parser()
    router_listen = None
    for name, service in services.items():
        argv = [str(a) for a in service["command"]]
        if argv[0] == "air-sitl":
            args = parser.parse_args(argv[1:])
            assert callable(args._run), name
            if args.command == "router":
                router_listen = args.listen
            if args.command == "serve":
                opts = bus_options_from_args(args)
                assert opts.publish and opts.config.connect == ("tcp/router:7447",)
                for url in args.mavlink:
                    spec = parse_link(url)
                    assert f"127.0.0.1:{spec.port}:{spec.port}" in service["ports"]
                assert (REPO / args.plan).is_file()
                # Inside a container 127.0.0.1 is the container: the video goes to the host,
                # where QGroundControl listens, by the name extra_hosts maps to it.
                assert str(args.video).startswith("udp://host.docker.internal:"), name
                assert "host.docker.internal:host-gateway" in service["extra_hosts"], name
        elif argv[0] == "ray":
            continue  # test_ray_nodes_start_a_cluster_the_sweep_can_join
        else:
            assert argv[:2] == ["python", "bridges/example_localizer.py"], name
            assert (REPO / argv[1]).is_file()
            args = localizer_parser().parse_args(argv[2:])
            assert args.zenoh_connect == ["tcp/router:7447"]
    assert router_listen == ["tcp/0.0.0.0:7447"]
    assert "127.0.0.1:7447:7447" in services["router"]["ports"]


def test_dockerfile_copies_what_exists_and_installs_the_cli() -> None:
    lines = (REPO / "Dockerfile").read_text().splitlines()
    assert any(re.fullmatch(r"FROM python:3\.1[1-9]\S*", ln) for ln in lines)
    copied = [shlex.split(ln)[1:-1] for ln in lines if ln.startswith("COPY ")]
    for sources in copied:
        for src in sources:
            assert (REPO / src).exists(), src
    assert any(re.fullmatch(r'RUN pip install "\.\$\{EXTRAS\}"', ln) for ln in lines)
    assert 'ARG EXTRAS=""' in lines  # the plain image installs no extra
    wanted = {"air_sitl", "bridges", "missions", "examples", "pyproject.toml"}
    assert wanted <= {s for c in copied for s in c}


def test_ray_nodes_start_a_cluster_the_sweep_can_join() -> None:
    """The compose profile "ray": a head and workers joining it, with options `ray start`
    (the version the [ray] extra installs) has; not started by a plain `docker compose up`."""
    services = compose()["services"]
    head, worker = services["ray-head"], services["ray-worker"]
    for service in (head, worker):
        assert service["profiles"] == ["ray"]
        assert service["command"][:2] == ["ray", "start"] and "--block" in service["command"]
        assert "./out:/out" in service["volumes"]
    assert "--head" in head["command"] and "--port=6379" in head["command"]
    assert "--address=ray-head:6379" in worker["command"] and worker["depends_on"] == ["ray-head"]
    pytest.importorskip("ray", reason="ray is not installed (the [ray] extra)")
    scripts = pytest.importorskip("ray.scripts.scripts")
    start = scripts.cli.commands["start"]  # ray's click command
    known = {opt for p in start.params for opt in p.opts}
    for service in (head, worker):
        for arg in service["command"][2:]:
            assert arg.split("=")[0] in known, arg


@pytest.mark.parametrize("service", ["router", "simulator", "localizer"])
def test_compose_commands_are_exec_form(service: str) -> None:
    # Exec form: signals reach our process, which exits 0 on SIGTERM (docker compose stop).
    assert isinstance(compose()["services"][service]["command"], list)
