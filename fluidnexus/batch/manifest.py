"""The batch manifest (TOML or JSON, docs/batch.md): scenes, where each comes from, its steps and their options.

Every problem is an :class:`InputError` naming the manifest, the entry (``scene[2] (sphere)``) and the field, so
a bad manifest stops the batch before anything runs.
"""
from __future__ import annotations

import json
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

from ..calibrate.assemble import PROTOCOLS
from ..errors import InputError
from .steps import NEEDS_RUN, PREPARE, SCENE_SOURCES, STEPS, StepCommands

NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")
SCENE_KEYS = {"name", "steps", "sample", "protocol", "from_pinf", "input", "novel", "ground_truth", "scene",
              "calibrate", *STEPS}
DEFAULT_KEYS = {"steps", "protocol", "calibrate", *STEPS}
ROLE_KEYS = ("input", "novel", "ground_truth")


@dataclass(frozen=True)
class SceneJob:
    """One scene of the batch: its name, its source (a dict, see :func:`_source`), the steps in order and each
    step's command-line options (``scene`` included: calibrate's extra options)."""

    name: str
    source: dict
    steps: tuple[str, ...]
    options: dict[str, list[str]]

    def to_dict(self) -> dict:
        return {"name": self.name, "source": self.source, "steps": list(self.steps), "options": self.options}


@dataclass(frozen=True)
class Manifest:
    path: Path
    data: dict
    scenes: tuple[SceneJob, ...]


def load_manifest(path: str | Path, commands: StepCommands) -> Manifest:
    """Read and check a manifest; relative paths in it are relative to its folder. ``commands`` says what each
    step's options are (``steps.StepCommands``)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, None, "manifest not found")
    text = path.read_text(errors="replace")
    try:
        data = json.loads(text) if path.suffix.lower() == ".json" else tomllib.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as err:
        kind = "JSON" if path.suffix.lower() == ".json" else "TOML"
        raise InputError(path, None, f"not valid {kind} ({err})") from None
    if not isinstance(data, dict):
        raise InputError(path, None, "expected a table with [defaults] and [[scene]] entries")
    _known(path, "manifest", data, {"defaults", "scene"})
    defaults = data.get("defaults", {})
    if not isinstance(defaults, dict):
        raise InputError(path, "defaults", "expected a table")
    _known(path, "defaults", defaults, DEFAULT_KEYS)
    entries = data.get("scene")
    if not isinstance(entries, list) or not entries or not all(isinstance(e, dict) for e in entries):
        raise InputError(path, "scene", "expected one [[scene]] table per scene (at least one)")
    scenes, seen = [], {}
    for i, entry in enumerate(entries):
        job = _scene(path, i, entry, defaults, commands)
        if job.name in seen:
            raise InputError(path, f"{_where(i, entry)}.name", f"duplicate name (also scene[{seen[job.name]}])")
        seen[job.name] = i
        scenes.append(job)
    return Manifest(path.resolve(), data, tuple(scenes))


def _where(i: int, entry: dict) -> str:
    name = entry.get("name")
    return f"scene[{i}] ({name})" if isinstance(name, str) else f"scene[{i}]"


def _known(path: Path, where: str, table: dict, known: set[str]) -> None:
    for key in table:
        if key not in known:
            raise InputError(path, f"{where}.{key}", f"unknown key; known: {', '.join(sorted(known))}")


def _scene(path: Path, i: int, entry: dict, defaults: dict, commands: StepCommands) -> SceneJob:
    where = _where(i, entry)
    _known(path, where, entry, SCENE_KEYS)
    name = entry.get("name")
    if not isinstance(name, str) or not NAME.match(name):
        raise InputError(path, f"{where}.name", "expected a folder name (letters, digits, '.', '_', '-')")
    source = _source(path, where, entry, defaults)
    steps = entry.get("steps", defaults.get("steps"))
    field = f"{where}.steps" if "steps" in entry else "defaults.steps"
    if not isinstance(steps, list) or not steps or not all(isinstance(s, str) for s in steps):
        raise InputError(path, field, f"expected a list of steps out of {', '.join(STEPS)}")
    for s in steps:
        if s not in STEPS:
            raise InputError(path, field, f"unknown step {s!r}; known: {', '.join(STEPS)}")
    if len(set(steps)) != len(steps):
        raise InputError(path, field, "a step is listed twice")
    for s in steps:
        if s in NEEDS_RUN and "recon" not in steps:
            raise InputError(path, field, f"{s} needs the reconstruction: add 'recon' to the steps")
    ordered = tuple(s for s in STEPS if s in steps)
    if source["kind"] == "scene" and "calibrate" in entry:
        raise InputError(path, f"{where}.calibrate", "a scene folder is copied as it is, not calibrated")
    options = {}
    for step in (PREPARE, *STEPS):  # every table is checked, also of a step this scene does not run
        key = "calibrate" if step == PREPARE else step
        tokens = _options(path, where, key, step, defaults.get(key, {}), entry.get(key, {}), commands,
                          check_required=step in ordered)
        if step == PREPARE and source["kind"] != "scene" or step in ordered:
            options[step] = tokens
    options.setdefault(PREPARE, [])
    return SceneJob(name, source, ordered, options)


def _options(path: Path, where: str, key: str, step: str, default: dict, own: dict, commands: StepCommands,
             check_required: bool) -> list[str]:
    """A step's options: the scene's table over the defaults' table, as command-line tokens."""
    for origin, table in (("defaults", default), (where, own)):
        if not isinstance(table, dict):
            raise InputError(path, f"{origin}.{key}", "expected a table of options, e.g. { frames = \"0:40\" }")
    merged = {**default, **own}
    tokens = []
    for name, value in merged.items():
        origin = where if name in own else "defaults"
        try:
            tokens += commands.option_tokens(step, name, value, path.parent)
        except ValueError as err:
            raise InputError(path, f"{origin}.{key}.{name}", str(err)) from None
    for name in commands.required(step) if check_required else ():
        if name not in merged:
            raise InputError(path, f"{where}.{key}.{name}", f"required by {key}")
    return tokens


def _source(path: Path, where: str, entry: dict, defaults: dict) -> dict:
    """``{"kind": "sample", "sample", "protocol"}``, ``{"kind": "from_pinf", "from_pinf", "input", ...}`` or
    ``{"kind": "scene", "scene"}`` with absolute paths."""
    from ..samples import sample_names

    given = [k for k in SCENE_SOURCES if k in entry]
    if len(given) != 1:
        raise InputError(path, f"{where}.{given[1] if given else 'sample'}",
                         "give exactly one of sample, from_pinf, scene")
    kind = given[0]
    roles = {k: entry[k] for k in ROLE_KEYS if k in entry}
    for k, names in roles.items():
        if kind != "from_pinf":
            raise InputError(path, f"{where}.{k}", "view roles go with from_pinf")
        if not isinstance(names, list) or not names or not all(isinstance(n, str) and n for n in names):
            raise InputError(path, f"{where}.{k}", "expected a list of view names")
    if "protocol" in entry and kind != "sample":
        raise InputError(path, f"{where}.protocol", "a protocol goes with sample")
    value = entry[kind]
    if not isinstance(value, str) or not value:
        raise InputError(path, f"{where}.{kind}", "expected a name or path")
    if kind == "sample":
        if value not in sample_names():
            raise InputError(path, f"{where}.sample", f"unknown sample {value!r}; known: {', '.join(sample_names())}")
        protocol = entry.get("protocol", defaults.get("protocol", "single-view"))
        if protocol not in PROTOCOLS:
            field = f"{where}.protocol" if "protocol" in entry else "defaults.protocol"
            raise InputError(path, field, f"unknown protocol {protocol!r}; known: {', '.join(sorted(PROTOCOLS))}")
        return {"kind": "sample", "sample": value, "protocol": protocol}
    target = (path.parent / value).resolve()
    if kind == "from_pinf":
        if not target.is_file():
            raise InputError(path, f"{where}.from_pinf", f"{target} not found")
        if "input" not in roles:
            raise InputError(path, f"{where}.input", "from_pinf needs the input view names")
        return {"kind": "from_pinf", "from_pinf": str(target), **roles}
    if not target.is_dir():
        raise InputError(path, f"{where}.scene", f"scene folder {target} not found")
    if not (target / "scene.json").is_file():
        raise InputError(path, f"{where}.scene", f"{target} is not a scene folder (no scene.json)")
    return {"kind": "scene", "scene": str(target)}
