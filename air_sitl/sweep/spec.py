"""A sweep SPEC (YAML) parsed and validated once into the runs it describes.

    base: {plan: missions/FL-200.plan, air-start: true, max-sim-time: 60}   # or scenario: FL-200
    axes: {map-date: [0, 1], wind: ["0@0", "5@270"], seed: [1, 2]}          # the product: 8 runs
    runs: [{plan: other.plan, seed: 7}]      # optional explicit runs, besides (or instead of) axes
    methods: [deadreckon, mapmatch]          # optional: localize + eval each run with these
    localizers: {mine: "python my_loc.py --name mine"}   # optional external programs, lockstep
    align: none                              # optional: eval's alignment (none, posyaw, se3, sim3)
    archives: /shared/sweep-runs             # optional: where workers write the run folders
    reference-date: 0                        # optional: the map date map-matching methods match

Option keys are ``air-sitl fly``'s long options without the dashes; a flag is ``true`` (``false``
or ``null`` leaves an option out); a list gives a repeatable option several times. ``plan`` paths
are relative to the SPEC file; ``scenario: FL-200`` names a plan of the missions folder. Every
run's options are checked by fly's own parser and validators here, before anything flies: a bad
key or value is one line naming the SPEC, where the value came from (``axes.wind[1]``) and the
run. A run's id is the hash of its resolved options (:func:`run_id`).
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

import yaml

from air_sitl.bus.args import bus_options_from_args
from air_sitl.camera.options import camera_from_args, map_choice_from_args
from air_sitl.commands.fly import add_arguments
from air_sitl.dataset.scenarios import missions_dir
from air_sitl.errors import AirSitlError
from air_sitl.eval.align import ALIGNMENTS
from air_sitl.localize import METHODS
from air_sitl.localize.external import ExternalLocalizer
from air_sitl.mission.geometry import shift_altitudes
from air_sitl.mission.plan_file import load_mission
from air_sitl.options import flight_options_from_args, int_in_range
from air_sitl.runner import home_of
from air_sitl.sweep.entries import method_problem, parse_localizer
from air_sitl.sweep.errors import SweepError

PLAN_KEYS = ("plan", "scenario")  # where a run's plan comes from (fly's positional PLAN)
MANAGED = ("out", "resume", "quiet")  # options the sweep sets itself
TOP_KEYS = (
    "base", "axes", "runs", "methods", "localizers", "align", "archives", "reference-date"
)  # fmt: skip
KEEP = ("all", "frames", "none")
ID_HEX = 12
SWEEP_RENDER_WORKERS = "0"  # one thread per run: a worker is one core (see executors)

Scalar = str | int | float | bool


@dataclass(frozen=True, slots=True, kw_only=True)
class RunSpec:
    """One run of a sweep: its options as the SPEC gave them, and fly's argv for them."""

    id: str
    options: dict[str, Any]  # key -> value after merging base, axis values, the run's own
    plan_label: str  # the plan as the SPEC names it (``missions/FL-200.plan``, ``FL-200``)
    plan_path: Path  # the plan file on the driver (its text travels with the task)
    argv: tuple[str, ...]  # fly's options without PLAN and --out (render workers included)
    seed: int


@dataclass(frozen=True, slots=True, kw_only=True)
class SweepSpec:
    """Everything a sweep runs: the runs, the methods and localizers scoring each, where to."""

    path: Path
    runs: tuple[RunSpec, ...]
    methods: tuple[str, ...] = ()
    localizers: tuple[ExternalLocalizer, ...] = ()
    align: str = "none"
    archives: Path | None = None  # None: OUT/runs
    axes: tuple[str, ...] = ()
    # The map date map-matching methods match against (None: date 0, or 1 for a flight over 0).
    reference_date: int | None = None


class _RaisingParser(argparse.ArgumentParser):
    """fly's parser, raising instead of printing usage and exiting."""

    def error(self, message: str) -> NoReturn:
        raise SweepError(message)


def fly_parser() -> argparse.ArgumentParser:
    """``air-sitl fly``'s own argument parser (what every run's options go through)."""
    parser = _RaisingParser(prog="air-sitl fly", add_help=False)
    add_arguments(parser)
    return parser


def run_id(options: Mapping[str, Any]) -> str:
    """The id of a run: the start of the SHA-256 of its resolved options (canonical JSON)."""
    text = json.dumps(options, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:ID_HEX]


def load_spec(path: Path, *, missions: Path | None = None) -> SweepSpec:
    """Read and validate a SPEC file (SweepError naming the file, the key and the run)."""
    where = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        msg = f"{where}: cannot read the SPEC: {err.strerror or err}"
        raise SweepError(msg) from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        at = f" (line {mark.line + 1})" if mark is not None else ""
        msg = f"{where}: not YAML{at}: {getattr(err, 'problem', None) or err}"
        raise SweepError(msg) from None
    if not isinstance(data, dict):
        msg = f"{where}: expected a mapping with base/axes/runs/methods, got {_kind(data)}"
        raise SweepError(msg)
    return parse_spec(data, path, missions=missions)


def parse_spec(data: Mapping[str, Any], path: Path, *, missions: Path | None = None) -> SweepSpec:
    """Validate the SPEC's content (``path``: its file, for messages and relative plans)."""
    where = str(path)
    for key in data:
        if key not in TOP_KEYS:
            msg = f"{where}: unknown key {key!r} (expected {', '.join(TOP_KEYS)})"
            raise SweepError(msg)
    parser = fly_parser()
    actions = _long_options(parser)
    base = _options(data.get("base"), "base", where, actions)
    axes = _axes(data.get("axes"), where, actions)
    explicit = _explicit_runs(data.get("runs"), where, actions)
    methods = _methods(data.get("methods"), where)
    localizers = _localizers(data.get("localizers"), where)
    align = data.get("align", "none")
    if align not in ALIGNMENTS:
        msg = f"{where}: align: {align!r} is not one of {', '.join(ALIGNMENTS)}"
        raise SweepError(msg)
    archives = data.get("archives")
    if archives is not None and not (isinstance(archives, str) and archives.strip()):
        msg = f"{where}: archives: expected a folder path, got {archives!r}"
        raise SweepError(msg)
    reference = data.get("reference-date")
    if reference is not None and (
        isinstance(reference, bool) or not isinstance(reference, int) or not 0 <= reference <= 99
    ):
        msg = f"{where}: reference-date: expected a map date 0-99, got {reference!r}"
        raise SweepError(msg)
    combos: list[tuple[dict[str, Any], dict[str, str]]] = []
    names = list(axes)
    for values in itertools.product(*(axes[name] for name in names)) if axes else ():
        picked = dict(zip(names, values, strict=True))
        origin = {n: f"axes.{n}[{axes[n].index(v)}]" for n, v in picked.items()}
        combos.append((picked, origin))
    for i, run in enumerate(explicit):
        combos.append((run, {k: f"runs[{i}].{k}" for k in run}))
    if not combos:
        combos.append(({}, {}))
    runs: list[RunSpec] = []
    seen: set[str] = set()
    plans: dict[Path, Any] = {}
    for n, (own, origin) in enumerate(combos):
        merged = {**base, **own}
        where_of = {**{k: f"base.{k}" for k in base}, **origin}
        if any(k in own for k in PLAN_KEYS):  # a run's own plan replaces base's, whichever key
            for k in PLAN_KEYS:
                if k not in own:
                    merged.pop(k, None)
        resolved = _resolve(merged, where_of, n, path, parser, missions, plans)
        if resolved.id not in seen:
            seen.add(resolved.id)
            runs.append(resolved)
    return SweepSpec(
        path=path,
        runs=tuple(runs),
        methods=methods,
        localizers=localizers,
        align=str(align),
        archives=None if archives is None else (path.parent / archives).resolve(),
        axes=tuple(names),
        reference_date=reference,
    )


def _kind(value: object) -> str:
    return "nothing" if value is None else type(value).__name__


def _long_options(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    return {
        opt[2:]: action
        for action in parser._actions  # argparse has no public list of its actions
        for opt in action.option_strings
        if opt.startswith("--")
    }


def _is_flag(action: argparse.Action) -> bool:
    return action.nargs == 0


def _is_repeatable(action: argparse.Action) -> bool:
    return isinstance(action, argparse._AppendAction)


def _check_value(
    key: str, value: Any, at: str, where: str, actions: Mapping[str, argparse.Action]
) -> None:
    """One option's value has the type its fly option takes (values themselves: later)."""
    if key in PLAN_KEYS:
        if not (isinstance(value, str) and value.strip()):
            what = "path" if key == "plan" else "name"
            msg = f"{where}: {at}: expected a plan {what}, got {value!r}"
            raise SweepError(msg)
        return
    if key in MANAGED:
        msg = f"{where}: {at}: {key!r} is set by the sweep itself (one folder per run)"
        raise SweepError(msg)
    action = actions.get(key)
    if action is None or key in ("help",):
        msg = f"{where}: {at}: unknown option {key!r} (not an option of air-sitl fly)"
        raise SweepError(msg)
    if value is None:
        return
    if _is_flag(action):
        if not isinstance(value, bool):
            msg = f"{where}: {at}: {key} is a flag: expected true or false, got {value!r}"
            raise SweepError(msg)
        return
    items = value if isinstance(value, list) and _is_repeatable(action) else [value]
    for item in items:
        if isinstance(item, bool) or not isinstance(item, str | int | float):
            what = "a value or a list of values" if _is_repeatable(action) else "one value"
            msg = f"{where}: {at}: {key} takes {what}, got {_kind(item)} {item!r}"
            raise SweepError(msg)


def _options(
    value: Any, at: str, where: str, actions: Mapping[str, argparse.Action]
) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, dict):
        msg = f"{where}: {at}: expected a mapping of fly options, got {_kind(value)}"
        raise SweepError(msg)
    for key, item in value.items():
        _check_value(str(key), item, f"{at}.{key}", where, actions)
    return {str(k): v for k, v in value.items()}


def _axes(value: Any, where: str, actions: Mapping[str, argparse.Action]) -> dict[str, list[Any]]:
    if value is None:
        return {}
    if not isinstance(value, dict):
        msg = f"{where}: axes: expected a mapping of option -> list of values, got {_kind(value)}"
        raise SweepError(msg)
    out: dict[str, list[Any]] = {}
    for key, values in value.items():
        if not isinstance(values, list):
            msg = f"{where}: axes.{key}: expected a list of values, got {_kind(values)} {values!r}"
            raise SweepError(msg)
        if not values:
            msg = f"{where}: axes.{key}: the axis is empty (give at least one value)"
            raise SweepError(msg)
        for i, item in enumerate(values):
            _check_value(str(key), item, f"axes.{key}[{i}]", where, actions)
        out[str(key)] = values
    return out


def _explicit_runs(
    value: Any, where: str, actions: Mapping[str, argparse.Action]
) -> list[dict[str, Any]]:
    if value is None:
        return []
    if not isinstance(value, list):
        msg = f"{where}: runs: expected a list of option mappings, got {_kind(value)}"
        raise SweepError(msg)
    return [_options(run, f"runs[{i}]", where, actions) for i, run in enumerate(value)]


def _methods(value: Any, where: str) -> tuple[str, ...]:
    if value is None:
        return ()
    if not isinstance(value, list) or not all(isinstance(m, str) for m in value):
        msg = f"{where}: methods: expected a list of method names, got {value!r}"
        raise SweepError(msg)
    problem = method_problem(value, tuple(METHODS))
    if problem is not None:
        msg = f"{where}: methods[{problem[0]}]: {problem[1]}"
        raise SweepError(msg)
    return tuple(value)


def _localizers(value: Any, where: str) -> tuple[ExternalLocalizer, ...]:
    if value is None:
        return ()
    if not isinstance(value, dict):
        msg = f"{where}: localizers: expected a mapping of name -> command, got {_kind(value)}"
        raise SweepError(msg)
    out = []
    for name, command in value.items():
        if not isinstance(command, str):
            msg = f"{where}: localizers.{name}: expected a command line, got {_kind(command)}"
            raise SweepError(msg)
        try:
            out.append(parse_localizer(f"{name}={command}"))
        except AirSitlError as err:
            msg = f"{where}: localizers.{name}: {err}"
            raise SweepError(msg) from None
    return tuple(out)


def _argv(options: Mapping[str, Any]) -> Iterator[str]:
    """fly's options for ``options`` (plan keys left out)."""
    for key, value in sorted(options.items()):
        if key in PLAN_KEYS or value is None or value is False:
            continue
        if value is True:
            yield f"--{key}"
            continue
        for item in value if isinstance(value, list) else [value]:
            yield f"--{key}={item}"


def _plan_path(
    options: Mapping[str, Any], spec: Path, missions: Path | None, at: str
) -> tuple[str, Path]:
    where = str(spec)
    if "plan" in options and "scenario" in options:
        msg = f"{where}: {at}: give a plan or a scenario, not both"
        raise SweepError(msg)
    if "plan" in options:
        label = str(options["plan"])
        return label, (spec.parent / label).resolve()
    if "scenario" in options:
        label = str(options["scenario"]).strip()
        folder = missions if missions is not None else missions_dir(None)
        path = folder / f"{label}.plan"
        if not path.is_file():
            msg = f"{where}: {at}: scenario {label!r} has no plan {path}"
            raise SweepError(msg)
        return label, path.resolve()
    msg = f"{where}: {at}: no plan (give base.plan or base.scenario, or one per run)"
    raise SweepError(msg)


_OPTION_IN_MESSAGE = re.compile(r"--([a-z][a-z0-9-]*)")


def _resolve(
    options: dict[str, Any],
    where_of: Mapping[str, str],
    n: int,
    spec: Path,
    parser: argparse.ArgumentParser,
    missions: Path | None,
    plans: dict[Path, Any],
) -> RunSpec:
    """Check one run's options with fly's parser and validators; its RunSpec."""
    ident = run_id(options)
    run_at = f"run {n + 1} ({ident})"
    plan_key = next((k for k in PLAN_KEYS if k in options), "plan")
    try:
        label, plan = _plan_path(options, spec, missions, f"{where_of.get(plan_key)}, {run_at}")
    except SweepError:
        raise
    except AirSitlError as err:  # no missions folder
        msg = f"{spec}: {where_of.get(plan_key, 'base')}, {run_at}: {err}"
        raise SweepError(msg) from None
    argv = list(_argv(options))
    if "render-workers" not in options:
        argv.append(f"--render-workers={SWEEP_RENDER_WORKERS}")
    try:
        args = parser.parse_args([str(plan), *argv])
        seed = _validate(args, plan, plans)
    except AirSitlError as err:
        text = str(err)
        named = _OPTION_IN_MESSAGE.findall(text)
        key = next((k for k in named if k in where_of), None)
        if key is None and any(k in ("plan", "PLAN") for k in text.split()):
            key = plan_key
        if key is None and str(plan) in text:
            key = plan_key
        at = where_of.get(key, "base") if key else "options"
        msg = f"{spec}: {at}, {run_at}: {text}"
        raise SweepError(msg) from None
    return RunSpec(
        id=ident,
        options=dict(sorted(options.items())),
        plan_label=label,
        plan_path=plan,
        argv=tuple(argv),
        seed=seed,
    )


def _validate(args: argparse.Namespace, plan: Path, plans: dict[Path, Any]) -> int:
    """fly's validators over parsed options (nothing opened: no map, no bus session)."""
    options = flight_options_from_args(args)
    if not args.no_camera:
        camera_from_args(args)
    map_choice_from_args(args)
    int_in_range("--render-workers", args.render_workers, 0, 64)
    bus_options_from_args(args)
    if plan not in plans:
        mission = load_mission(plan)
        plans[plan] = (mission, home_of(mission))
    mission, home = plans[plan]
    shift_altitudes(mission, options.altitude_offset_m, home)
    return options.seed


def needs_camera(spec: SweepSpec) -> None:
    """Methods and localizers score camera archives: refuse runs flown with no-camera."""
    if not (spec.methods or spec.localizers):
        return
    for run in spec.runs:
        if run.options.get("no-camera") is True:
            msg = (
                f"{spec.path}: no-camera, run {run.id}: methods and localizers need the "
                "camera archive; fly these runs with the camera"
            )
            raise SweepError(msg)


def describe(run: RunSpec, keys: Sequence[str]) -> str:
    """``map-date=1 wind=5@270 seed=2`` (the axes of a run, for progress lines)."""
    parts = [f"{k}={run.options[k]}" for k in keys if k in run.options]
    return " ".join(parts) if parts else run.plan_label
