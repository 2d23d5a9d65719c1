"""Reading scenario files: YAML 1.2 (ruamel.yaml) validated by :mod:`asvtwin.scenarios.schema`.

ruamel.yaml reads YAML 1.2, where ``NO`` is the string "NO" (Norway's country code, a
callsign) and ``12:30`` is the string "12:30", not ``False`` and 750 as in YAML 1.1 readers
such as PyYAML. Its round-trip loader also keeps the line of every key, which turns a
pydantic error location such as ``targets[1].speed_kn`` into ``head_on.yaml:23``.

Every problem raises :class:`~asvtwin.errors.ScenarioError` whose message names the file,
the line, the field, the allowed range and the value found, e.g.::

    crossing.yaml:14: field 'own_ship.heading_deg': Input should be less than 360;
    allowed: >= 0 and < 360 (initial heading, clockwise from north [deg]), actually: 400

Geometry is checked against the scene's land after validation (:func:`geometry_problems`):
every start position, waypoint and leg, and the straight track of every constant-velocity
target over the scenario's duration, must be on water inside the scene.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Iterator
from importlib import resources
from pathlib import Path
from typing import Any, Literal, get_args

import annotated_types as at
import numpy as np
from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo
from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.error import MarkedYAMLError, YAMLError

from asvtwin.errors import AsvTwinError, ScenarioError
from asvtwin.geo import Scene, default_scene, load_scene
from asvtwin.scenarios.schema import (
    AisReplay,
    Colreg,
    ConstantVelocity,
    GeoPosition,
    NedPosition,
    Scenario,
    TargetSpec,
    Waypoints,
)
from asvtwin.units import KNOT_M_S

__all__ = [
    "DEFAULT_SCENE",
    "check_geometry",
    "default_scenario",
    "file_problems",
    "geometry_problems",
    "library_names",
    "library_path",
    "load_any",
    "load_library",
    "load_scenario",
    "parse_scenario",
    "resolve_scene",
]

#: Name of the bundled scene (the Trondheim Fjord).
DEFAULT_SCENE = "trondheim"
_LIBRARY = "library"
#: Spacing of the points checked along a leg, in hull lengths of the own ship (>= 1 m).
_LEG_STEP_M = 5.0
#: Discriminator tags of the unions, for naming the fields of an error location.
_TAGS: dict[str, type[BaseModel]] = {
    "geo": GeoPosition,
    "ned": NedPosition,
    "constant_velocity": ConstantVelocity,
    "waypoints": Waypoints,
    "ais_replay": AisReplay,
    "colreg": Colreg,
}

Loc = tuple[str | int, ...]


# --------------------------------------------------------------------------- YAML


def _plain(node: Any) -> Any:
    """ruamel's round-trip nodes as plain dict/list/str/int/float/bool/datetime."""
    if isinstance(node, dict):
        return {str(k): _plain(v) for k, v in node.items()}
    if isinstance(node, list):
        return [_plain(v) for v in node]
    if isinstance(node, bool) or node is None:
        return node
    if isinstance(node, int):
        return int(node)
    if isinstance(node, float):
        return float(node)
    if isinstance(node, str):
        return str(node)
    return node


def _read_yaml(text: str, label: str) -> Any:
    yaml = YAML(typ="rt")
    yaml.version = (1, 2)  # type: ignore[assignment]
    try:
        return yaml.load(text)
    except MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = f":{mark.line + 1}" if mark is not None else ""
        problem = exc.problem or exc.context or "malformed YAML"
        raise ScenarioError(f"{label}{line}: not valid YAML: {problem}") from exc
    except YAMLError as exc:
        raise ScenarioError(f"{label}: not valid YAML: {exc}") from exc


def _line(root: Any, loc: Loc) -> int | None:
    """1-based line of the deepest node of ``loc`` present in the YAML tree."""
    node, line = root, None
    for part in loc:
        if isinstance(node, CommentedMap) and isinstance(part, str) and part in node:
            line = node.lc.key(part)[0] + 1
            node = node[part]
        elif isinstance(node, CommentedSeq) and isinstance(part, int) and 0 <= part < len(node):
            line = node.lc.item(part)[0] + 1
            node = node[part]
        # else: a union tag ("geo", "waypoints") or a missing key: stay on this node
    if line is None and isinstance(root, CommentedMap) and root.lc.line is not None:
        line = root.lc.line + 1
    return line


# --------------------------------------------------------------------------- messages


def _models_in(annotation: Any) -> list[type[BaseModel]]:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    out: list[type[BaseModel]] = []
    for arg in get_args(annotation):
        out.extend(_models_in(arg))
    return out


def _walk(loc: Loc) -> tuple[type[BaseModel] | None, FieldInfo | None, list[str]]:
    """The model holding the last field of ``loc``, that field, and the dotted names."""
    cls: type[BaseModel] | None = Scenario
    info: FieldInfo | None = None
    names: list[str] = []
    for part in loc:
        if isinstance(part, int):
            names[-1:] = [f"{names[-1]}[{part}]"] if names else [f"[{part}]"]
            continue
        if part in _TAGS and (cls is None or part not in cls.model_fields):
            cls = _TAGS[part]
            continue
        names.append(part)
        if cls is None or part not in cls.model_fields:
            cls, info = None, None
            continue
        info = cls.model_fields[part]
        models = _models_in(info.annotation)
        owner = cls
        cls = models[0] if len(models) == 1 else None
        if part == loc[-1]:
            cls = owner
    return cls, info, names


def _fmt(x: object) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


def _allowed(info: FieldInfo | None) -> str:
    """The allowed values of a field, from its constraints and its description."""
    if info is None:
        return ""
    parts: list[str] = []
    for m in info.metadata:
        if isinstance(m, at.Ge):
            parts.append(f">= {_fmt(m.ge)}")
        elif isinstance(m, at.Gt):
            parts.append(f"> {_fmt(m.gt)}")
        elif isinstance(m, at.Le):
            parts.append(f"<= {_fmt(m.le)}")
        elif isinstance(m, at.Lt):
            parts.append(f"< {_fmt(m.lt)}")
        elif isinstance(m, at.MinLen):
            parts.append(f"length >= {m.min_length}")
        elif isinstance(m, at.MaxLen):
            parts.append(f"length <= {m.max_length}")
    lits = [a for a in _literal_args(info.annotation)]
    if lits:
        parts.append("one of " + ", ".join(repr(a) for a in lits))
    text = " and ".join(parts)
    if info.description:
        text = f"{text} ({info.description})" if text else info.description
    return text


def _literal_args(annotation: Any) -> list[Any]:
    if getattr(annotation, "__origin__", None) is Literal:
        return list(get_args(annotation))
    out: list[Any] = []
    for arg in get_args(annotation):
        if getattr(arg, "__origin__", None) is Literal:
            out.extend(get_args(arg))
    return out


def _describe(err: Any, root: Any, label: str) -> str:
    loc: Loc = tuple(err["loc"])
    line = _line(root, loc)
    where = f"{label}:{line}" if line is not None else label
    kind = err["type"]
    if kind == "extra_forbidden":
        owner, _, names = _walk(loc[:-1]) if len(loc) > 1 else (Scenario, None, [])
        if len(loc) > 1 and owner is not None and names:
            # _walk returns the owner of the last field; we want the model of that field
            _, info, _ = _walk(loc[:-1])
            models = _models_in(info.annotation) if info is not None else []
            owner = models[0] if len(models) == 1 else None
        if len(loc) > 1 and isinstance(loc[-2], str) and loc[-2] in _TAGS:
            owner = _TAGS[loc[-2]]
        allowed = ", ".join(owner.model_fields) if owner is not None else "see the schema"
        field = ".".join(names + [str(loc[-1])]) if names else str(loc[-1])
        return f"{where}: unknown field {field!r}; allowed fields here: {allowed}"
    _, info, names = _walk(loc)
    field = ".".join(names) if names else "<scenario>"
    msg = err["msg"]
    msg = msg.removeprefix("Value error, ")
    if kind == "missing":
        desc = f" ({info.description})" if info is not None and info.description else ""
        return f"{where}: field {field!r} is required{desc}"
    text = f"{where}: field {field!r}: {msg}"
    if kind == "literal_error":
        allowed = info.description if info is not None and info.description else ""
    else:
        allowed = _allowed(info) if kind != "value_error" else ""
    if allowed:
        text += f"; allowed: {allowed}"
    if kind != "value_error":
        text += f", actually: {err['input']!r}"
    return text


def _validation_error(exc: ValidationError, root: Any, label: str) -> ScenarioError:
    errors = exc.errors(include_url=False)
    lines = [_describe(e, root, label) for e in errors[:10]]
    if len(errors) > 10:
        lines.append(f"... and {len(errors) - 10} more")
    head = lines[0] if len(lines) == 1 else f"{label}: {len(errors)} problems:\n  " + "\n  ".join(lines)
    return ScenarioError(head)


# --------------------------------------------------------------------------- paths


def _resolve_paths(doc: dict[str, Any], base_dir: Path) -> None:
    """Make the relative file paths of a decoded scenario absolute, from ``base_dir``."""

    def fix(obj: Any, key: str) -> None:
        if isinstance(obj, dict) and isinstance(obj.get(key), str) and obj[key]:
            p = Path(os.path.expanduser(obj[key]))
            if not p.is_absolute():
                obj[key] = str(base_dir / p)

    if isinstance(doc.get("scene"), str) and doc["scene"] != DEFAULT_SCENE:
        fix(doc, "scene")
    fix(doc.get("ais"), "path")
    fix(doc.get("weather"), "path")
    for t in doc.get("targets") or []:
        if isinstance(t, dict):
            fix(t.get("behaviour"), "file")


# --------------------------------------------------------------------------- geometry


def resolve_scene(scenario: Scenario) -> Scene:
    """The scene a scenario names: the bundled fjord for ``"trondheim"``, else the file."""
    if scenario.scene == DEFAULT_SCENE:
        return default_scene()
    return _load_scene_cached(scenario.scene)


@functools.lru_cache(maxsize=8)
def _load_scene_cached(path: str) -> Scene:
    try:
        return load_scene(path)
    except AsvTwinError as exc:
        raise ScenarioError(f"scene {path!r} cannot be loaded: {exc}") from exc


def _samples(a: np.ndarray, b: np.ndarray, step_m: float) -> np.ndarray:
    n = max(2, math.ceil(float(np.linalg.norm(b - a)) / step_m) + 1)
    s = np.linspace(0.0, 1.0, n)[:, None]
    return a[None, :] + s * (b - a)[None, :]


def _route_problems(
    scene: Scene, start: np.ndarray | None, route: list[np.ndarray], loc: Loc, step_m: float,
    *, loop: bool = False, start_loc: Loc | None = None,
) -> Iterator[tuple[Loc, str]]:
    import shapely

    pts = ([start] if start is not None else []) + route
    locs: list[Loc] = ([start_loc] if start is not None and start_loc else []) + [
        (*loc, k) for k in range(len(route))
    ]
    if not pts:
        return
    arr = np.array(pts)
    on_land = scene.land.contains(arr)
    inside = shapely.contains_xy(scene.boundary_ned, arr[:, 0], arr[:, 1])
    for k, (p, where) in enumerate(zip(arr, locs, strict=True)):
        if not inside[k]:
            yield where, f"position (north {p[0]:.0f} m, east {p[1]:.0f} m) is outside the scene"
        elif on_land[k]:
            yield where, f"position (north {p[0]:.0f} m, east {p[1]:.0f} m) is on land"
    legs = list(zip(arr[:-1], arr[1:], locs[1:], strict=True))
    if loop and len(arr) > 2:
        legs.append((arr[-1], arr[0 if start is None else 1], locs[0 if start is None else 1]))
    for a, b, where in legs:
        xs = _samples(a, b, step_m)
        land = scene.land.contains(xs)
        if land.any():
            hit = xs[int(np.argmax(land))]
            yield where, (
                f"the leg to this waypoint crosses land at north {hit[0]:.0f} m, "
                f"east {hit[1]:.0f} m"
            )


def geometry_problems(scenario: Scenario, scene: Scene | None = None) -> list[tuple[Loc, str]]:
    """Every place where the scenario's geometry meets land or leaves the scene.

    Checks the own ship's start, waypoints and legs; each target's start and route legs;
    and the straight track a constant-velocity (or route-less COLREG) target sails over the
    scenario's duration. Legs are sampled every 5 m (0.1 m for the model-scale hull).

    Returns
    -------
    list of (location, message)
        ``location`` is the field path (as in a pydantic error), empty when all is well.
    """
    scene = scene if scene is not None else resolve_scene(scenario)
    frame = scene.frame
    own = scenario.own_ship
    step = _LEG_STEP_M if own.vessel == "cybership2_full_scale" else 0.1
    out: list[tuple[Loc, str]] = []
    out.extend(_route_problems(
        scene, own.start.to_ned(frame), [p.to_ned(frame) for p in own.route],
        ("own_ship", "route"), step, start_loc=("own_ship", "start"),
    ))
    for i, t in enumerate(scenario.targets):
        out.extend(_target_problems(scene, scenario, t, i))
    return out


def _target_problems(
    scene: Scene, scenario: Scenario, t: TargetSpec, i: int
) -> Iterator[tuple[Loc, str]]:
    frame = scene.frame
    b = t.behaviour
    if t.start is None:  # ais_replay: the log says where
        return
    start = t.start.to_ned(frame)
    step = max(1.0, min(_LEG_STEP_M, t.length_m / 10.0))
    base: Loc = ("targets", i)
    route: list[np.ndarray] = []
    if isinstance(b, Waypoints | Colreg):
        route = [p.to_ned(frame) for p in b.route]
    yield from _route_problems(
        scene, start, route, (*base, "behaviour", "route"), step,
        loop=isinstance(b, Waypoints) and b.loop, start_loc=(*base, "start"),
    )
    if isinstance(b, ConstantVelocity) or (isinstance(b, Colreg) and not b.route):
        run_m = t.speed_kn * KNOT_M_S * scenario.duration_s
        if run_m > 0:
            psi = math.radians(t.heading_deg)
            end = start + run_m * np.array([math.cos(psi), math.sin(psi)])
            xs = _samples(start, end, step)
            land = scene.land.contains(xs)
            if land.any():
                k = int(np.argmax(land))
                dist = float(np.linalg.norm(xs[k] - start))
                yield (*base, "heading_deg"), (
                    f"on this heading at {t.speed_kn:g} kn the target reaches land after "
                    f"{dist:.0f} m ({dist / (t.speed_kn * KNOT_M_S):.0f} s of the "
                    f"{scenario.duration_s:g} s run)"
                )


def file_problems(scenario: Scenario) -> list[tuple[Loc, str]]:
    """Every file the scenario names (scene, AIS log, forecast, replayed logs) that is not a
    readable file. Relative paths count from the working directory (the loader has already
    made them absolute from the scenario's folder)."""
    out: list[tuple[Loc, str]] = []

    def need(path: str | None, loc: Loc) -> None:
        if path and not Path(path).is_file():
            out.append((loc, f"no such file: {path}"))

    if scenario.scene != DEFAULT_SCENE:
        need(scenario.scene, ("scene",))
    if scenario.ais.mode == "file":
        need(scenario.ais.path, ("ais", "path"))
    if scenario.weather.mode == "file":
        need(scenario.weather.path, ("weather", "path"))
    for i, t in enumerate(scenario.targets):
        if isinstance(t.behaviour, AisReplay):
            need(t.behaviour.file, ("targets", i, "behaviour", "file"))
    return out


def _raise_problems(problems: list[tuple[Loc, str]], label: str, root: Any) -> None:
    if not problems:
        return
    lines = []
    for loc, msg in problems:
        line = _line(root, loc) if root is not None else None
        where = f"{label}:{line}" if line is not None else label
        _, _, names = _walk(loc)
        lines.append(f"{where}: field {'.'.join(names)!r}: {msg}")
    if len(lines) == 1:
        raise ScenarioError(lines[0])
    raise ScenarioError(f"{label}: {len(lines)} problems:\n  " + "\n  ".join(lines))


def check_geometry(scenario: Scenario, scene: Scene | None = None, *, label: str = "<scenario>",
                   root: Any = None) -> None:
    """Raise :class:`ScenarioError` listing every :func:`geometry_problems` entry."""
    _raise_problems(geometry_problems(scenario, scene), label, root)


# --------------------------------------------------------------------------- public API


def parse_scenario(
    text: str, source: str = "<string>", *, base_dir: str | os.PathLike[str] | None = None,
    check_scene: bool = True,
) -> Scenario:
    """Validate a scenario given as YAML text.

    Parameters
    ----------
    text : str
        The YAML document.
    source : str
        Name used in error messages (the file name).
    base_dir : path-like, optional
        Directory that relative paths in the file (scene, AIS log, forecast) start from.
    check_scene : bool
        Also check the geometry against the scene's land (:func:`geometry_problems`).

    Raises
    ------
    ScenarioError
        Naming the file, the line, the field, the allowed range and the value found.
    """
    root = _read_yaml(text, source)
    if not isinstance(root, dict):
        found = "an empty document" if root is None else type(root).__name__
        raise ScenarioError(f"{source}: a scenario must be a YAML mapping, actually: {found}")
    doc = _plain(root)
    if base_dir is not None:
        _resolve_paths(doc, Path(base_dir))
    try:
        scenario = Scenario.model_validate(doc)
    except ValidationError as exc:
        raise _validation_error(exc, root, source) from exc
    _raise_problems(file_problems(scenario), source, root)
    if check_scene:
        check_geometry(scenario, resolve_scene(scenario), label=source, root=root)
    return scenario


def load_scenario(path: str | os.PathLike[str], *, check_scene: bool = True) -> Scenario:
    """Read and validate a scenario file (relative paths inside start from its directory).

    Raises
    ------
    ScenarioError
        If the file cannot be read or is not a valid scenario (file, line, field, range).
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{p}: cannot read the scenario file: {exc}") from exc
    return parse_scenario(text, str(p), base_dir=p.parent, check_scene=check_scene)


def _library_dir() -> Path:
    return Path(str(resources.files("asvtwin.scenarios") / _LIBRARY))


def library_names() -> list[str]:
    """Names of the scenarios shipped with the package (file stems, sorted)."""
    return sorted(p.stem for p in _library_dir().glob("*.yaml"))


def library_path(name: str) -> Path:
    """The file of a library scenario.

    Raises
    ------
    ScenarioError
        If there is no such scenario; the message lists the names.
    """
    p = _library_dir() / f"{name}.yaml"
    if not name or "/" in name or not p.is_file():
        raise ScenarioError(
            f"no library scenario {name!r}; available: {', '.join(library_names())}"
        )
    return p


def load_library(name: str, *, check_scene: bool = True) -> Scenario:
    """Load a library scenario by name (see :func:`library_names`)."""
    return load_scenario(library_path(name), check_scene=check_scene)


def load_any(ref: str | os.PathLike[str], *, check_scene: bool = True) -> Scenario:
    """A scenario file if ``ref`` is an existing path, else a library scenario by name.

    Raises
    ------
    ScenarioError
        Neither a file nor a library name (the message lists the library), or invalid.
    """
    p = Path(ref)
    if p.exists():
        return load_scenario(p, check_scene=check_scene)
    name = str(ref)
    if name in library_names():
        return load_library(name, check_scene=check_scene)
    raise ScenarioError(
        f"{name}: no such scenario file, nor a library scenario; library: "
        f"{', '.join(library_names())}"
    )


def default_scenario() -> Scenario:
    """The embedded default: the Trondheim scene, synthetic AIS through the NMEA path, the
    weather fixture, the full-scale own ship under ``rl_psf``: the shipped policy through
    the safety filter (``library/default.yaml``)."""
    return load_library("default", check_scene=False)
