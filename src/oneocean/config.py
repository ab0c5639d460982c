"""Load and validate the workflow configuration against its JSON schema.

The schema (package data ``oneocean/data/config.schema.yaml``) documents every key and its
default; :func:`load_schema` fills in the task and method enums from :mod:`oneocean.registry`.
This module fills the defaults and turns the first violation into a one-line
:class:`~oneocean.errors.ConfigError` that names the offending key.
"""

from __future__ import annotations

import copy
import math
import re
from datetime import datetime
from importlib import resources
from pathlib import Path

import jsonschema
import yaml

from . import registry
from .errors import ConfigError

#: Schema shipped as package data (the single source of truth for keys and defaults; task and
#: method enums are injected from the registry by :func:`load_schema`).
SCHEMA_PATH = Path(str(resources.files("oneocean") / "data" / "config.schema.yaml"))


def load_schema(path: str | Path | None = None) -> dict:
    """The config schema, with the task and method enums of the registry filled in.

    ``rollouts.tasks`` and ``rollouts.methods`` are restricted to the tasks and methods
    registered now, ``rollouts.tasks`` defaulting to the packaged task ladder; ``scenes.tasks``
    is restricted to (and defaults to) the tasks with scene tiers, ``scenes.methods`` to the
    methods; ``rl.tasks`` is restricted to the tasks and defaults to the navigation family's.

    Parameters
    ----------
    path : str or pathlib.Path, optional
        A schema YAML file; default the packaged one (:data:`SCHEMA_PATH`).

    Returns
    -------
    dict
        The JSON schema (a new dict on every call).
    """
    if path is None:
        text = (resources.files("oneocean") / "data" / "config.schema.yaml").read_text()
    else:
        text = Path(path).read_text()
    schema = yaml.safe_load(text)
    rollouts = schema.get("properties", {}).get("rollouts", {}).get("properties", {})
    if "tasks" in rollouts:
        rollouts["tasks"]["items"] = {"enum": list(registry.task_ids())}
        rollouts["tasks"].setdefault("default", list(registry.builtin_task_ids()))
    if "methods" in rollouts:
        rollouts["methods"]["items"] = {"enum": list(registry.method_names())}
        rollouts["methods"].setdefault("default", list(registry.builtin_method_names()))
    scenes = schema.get("properties", {}).get("scenes", {}).get("properties", {})
    if "tasks" in scenes:   # the tasks whose tier table has scene_tiers
        scenes["tasks"]["items"] = {"enum": list(registry.scene_tasks())}
        scenes["tasks"].setdefault("default", list(registry.scene_tasks()))
    if "methods" in scenes:
        scenes["methods"]["items"] = {"enum": list(registry.method_names())}
    rl = schema.get("properties", {}).get("rl", {}).get("properties", {})
    if "tasks" in rl:   # the PPO baseline: default the navigation family's (single-vehicle)
        rl["tasks"]["items"] = {"enum": list(registry.task_ids())}
        rl["tasks"].setdefault("default", [t for t in registry.builtin_task_ids()
                                           if registry.task_spec(t).family == "navigation"])
    return schema


def _with_defaults(validator_cls):
    """A jsonschema validator class that fills ``default`` values while validating."""
    validate_props = validator_cls.VALIDATORS["properties"]

    def set_defaults(validator, properties, instance, schema):
        if isinstance(instance, dict):
            for key, sub in properties.items():
                if "default" in sub and key not in instance:
                    instance[key] = copy.deepcopy(sub["default"])
                elif "$ref" in sub and key not in instance and "default" in sub:
                    instance[key] = copy.deepcopy(sub["default"])
        yield from validate_props(validator, properties, instance, schema)

    return jsonschema.validators.extend(validator_cls, {"properties": set_defaults})


_Filling = _with_defaults(jsonschema.Draft202012Validator)


def _key(error: jsonschema.ValidationError) -> str:
    path = ".".join(str(p) for p in error.absolute_path)
    if error.validator == "additionalProperties":
        extra = sorted(set(error.instance) - set(error.schema.get("properties", {})))
        known = ", ".join(sorted(error.schema.get("properties", {})))
        where = f"{path}." if path else ""
        return f"unknown key '{where}{extra[0]}' (known keys here: {known})"
    return f"key '{path or '<root>'}': {error.message}"


_INT = re.compile(r"[-+]?[0-9]+")
_BOOLS = {"true": True, "yes": True, "on": True, "false": False, "no": False, "off": False}
_NULLS = ("null", "Null", "NULL", "~")


def _types(schema: dict) -> set:
    t = schema.get("type", ())
    return {t} if isinstance(t, str) else set(t)


def _scalar(text: str, schema: dict):
    """``text`` as the integer/number/boolean/null the schema asks for (``text`` itself when
    the schema accepts a string there or the text is no such value)."""
    types, enum = _types(schema), schema.get("enum")
    if "string" in types or (enum is not None and text in enum) or (
            not types and enum is None):
        return text
    s = text.strip()
    candidates = []
    if _INT.fullmatch(s):
        candidates.append(int(s))
    else:
        try:
            value = float(s)
        except ValueError:
            pass
        else:
            if math.isfinite(value):
                candidates.append(value)
    if s.lower() in _BOOLS:
        candidates.append(_BOOLS[s.lower()])
    if s in _NULLS:
        candidates.append(None)
    for value in candidates:
        if enum is not None:
            if any(type(value) is type(e) and value == e for e in enum):
                return value
        elif value is None:
            if "null" in types:
                return None
        elif isinstance(value, bool):
            if "boolean" in types:
                return value
        elif isinstance(value, int):
            if types & {"integer", "number"}:
                return value
        elif "number" in types:
            return value
        elif "integer" in types and value.is_integer():
            return int(value)
    return text


def coerce_strings(instance, schema: dict, root: dict | None = None):
    """Turn strings that spell a number, boolean or null into that value where the schema asks.

    A string is converted wherever ``schema`` asks for an integer, number, boolean or null and
    not a string. ``snakemake --config 'rollouts={"episodes": 5}'`` parses nested values as
    strings (``"5"``); this lets such overrides validate while ``"five"`` still fails
    validation.

    Parameters
    ----------
    instance : object
        The config (or a part of it); dicts and lists are changed in place.
    schema : dict
        The JSON schema (or subschema) ``instance`` must match; local ``$ref``, ``allOf``,
        ``oneOf`` and ``anyOf`` are followed.
    root : dict, optional
        The whole schema, against which ``$ref`` resolves; default ``schema``.

    Returns
    -------
    object
        ``instance`` coerced: the same dict or list, or the new scalar (which the caller must
        use for a scalar ``instance``).
    """
    root = schema if root is None else root
    ref = schema.get("$ref")
    if isinstance(ref, str) and ref.startswith("#/"):
        target = root
        for part in ref[2:].split("/"):
            target = target.get(part, {})
        schema = {**target, **{k: v for k, v in schema.items() if k != "$ref"}}
    for sub in schema.get("allOf", ()):
        instance = coerce_strings(instance, sub, root)
    branches = list(schema.get("oneOf", ())) + list(schema.get("anyOf", ()))
    if branches:
        def valid(value, sub):
            return jsonschema.Draft202012Validator(
                {**sub, "$defs": root.get("$defs", {})}).is_valid(value)

        if any(valid(instance, sub) for sub in branches):
            return instance     # already valid as it is: nothing to coerce
        for sub in branches:    # else the first branch the coerced value is valid against
            trial = coerce_strings(copy.deepcopy(instance), sub, root)
            if valid(trial, sub):
                if isinstance(instance, (dict, list)) and type(trial) is type(instance):
                    instance.clear()
                    (instance.update if isinstance(instance, dict) else instance.extend)(trial)
                    return instance
                return trial
        return instance
    if isinstance(instance, str):
        return _scalar(instance, schema)
    if isinstance(instance, dict):
        props = schema.get("properties", {})
        extra = schema.get("additionalProperties")
        for key in list(instance):
            sub = props.get(key, extra if isinstance(extra, dict) else None)
            if sub is not None:
                instance[key] = coerce_strings(instance[key], sub, root)
    elif isinstance(instance, list) and isinstance(schema.get("items"), dict):
        for i, item in enumerate(instance):
            instance[i] = coerce_strings(item, schema["items"], root)
    return instance


def validate_config(config: dict, schema: dict | None = None) -> dict:
    """Validate ``config`` in place against the schema, fill defaults, and return it.

    First the config's ``plugins`` are imported (they may register tasks and methods); strings
    are coerced (:func:`coerce_strings`); after the schema, the checks it cannot express run
    (region and sources, held-out seeds, LLM models, scenes) and one ``planner`` method per
    ``llm.models`` entry is registered (:func:`register_llm_methods`).

    Parameters
    ----------
    config : dict
        The merged config, changed in place.
    schema : dict, optional
        The JSON schema; default :func:`load_schema`.

    Returns
    -------
    dict
        ``config``, validated, defaults filled.

    Raises
    ------
    ConfigError
        One line naming the first bad key: unknown, ill-typed, out of range, or inconsistent.
    """
    registry.load_plugins(config.get("plugins") if isinstance(config, dict) else None)
    schema = schema or load_schema()
    coerce_strings(config, schema)   # e.g. snakemake --config 'rollouts={"episodes": "5"}'
    validator = _Filling(schema, format_checker=jsonschema.FormatChecker())
    errors = sorted(validator.iter_errors(config), key=lambda e: list(map(str, e.absolute_path)))
    if errors:
        raise ConfigError(f"config {_key(errors[0])}")
    _check_semantics(config)
    return config


def _check_semantics(cfg: dict) -> None:
    _check_data(cfg)
    _check_held_out(cfg["rollouts"])
    if int(cfg["rollouts"]["seed"]) in [int(x) for x in cfg["bc"]["train_seeds"]]:
        raise ConfigError(f"config key 'bc.train_seeds': {cfg['bc']['train_seeds']} contains "
                          f"the evaluation seed {cfg['rollouts']['seed']} (rollouts.seed); "
                          "training seeds must be disjoint from it")
    held = [int(cfg["rollouts"]["seed"])] + [
        int(x) for x in (cfg["rollouts"].get("replicate") or {}).get("seeds", [])]
    both = sorted(set(int(x) for x in cfg["rl"]["seeds"]) & set(held))
    if both:
        raise ConfigError(f"config key 'rl.seeds': {both} is an evaluation seed (rollouts.seed "
                          "or rollouts.replicate.seeds); training seeds must be disjoint "
                          "from them")
    for m in cfg["llm"]["models"]:
        if not (m.get("model_path") or (m.get("base_url") and m.get("model"))):
            raise ConfigError(f"config key 'llm.models' entry {m['name']!r}: needs base_url "
                              "and model (an endpoint) or model_path (a local GGUF file)")
    names = [m["name"] for m in cfg["llm"]["models"]]
    if len(set(names)) != len(names):
        raise ConfigError(f"config key 'llm.models': duplicate name in {names}")
    _check_scenes(cfg)
    register_llm_methods(cfg)


#: The sections a region's product depends on (what :func:`validate_data_config` checks).
DATA_SECTIONS = ("region", "sources", "synthetic", "cmems", "gebco", "etopo", "files",
                 "variants")


def validate_data_config(config: dict, where: str = "config") -> dict:
    """Validate and fill only the sections a region's product depends on.

    The sections are :data:`DATA_SECTIONS` (the region, its sources and their blocks, the
    variants); they are checked against the packaged schema, with the same region and source
    checks as :func:`validate_config`. Other top-level keys must be known to the schema but
    are not checked (no plugins, no task registry).

    Parameters
    ----------
    config : dict
        A config (or a region file's mapping); not changed.
    where : str, default "config"
        Names the config in the errors, e.g. a region file's path.

    Returns
    -------
    dict
        A new dict of just those sections, defaults filled.

    Raises
    ------
    ConfigError
        One line: ``where`` and the first bad key.
    """
    if not isinstance(config, dict):
        raise ConfigError(f"{where}: the top level must be a mapping")
    schema = yaml.safe_load(SCHEMA_PATH.read_text())
    props = schema["properties"]
    unknown = sorted(set(config) - set(props))
    if unknown:
        raise ConfigError(f"{where}: unknown key '{unknown[0]}' (known keys here: "
                          f"{', '.join(sorted(props))})")
    sub = {k: copy.deepcopy(config[k]) for k in DATA_SECTIONS if k in config}
    data_schema = {**schema, "properties": {k: props[k] for k in DATA_SECTIONS}}
    coerce_strings(sub, data_schema)
    validator = _Filling(data_schema, format_checker=jsonschema.FormatChecker())
    errors = sorted(validator.iter_errors(sub), key=lambda e: list(map(str, e.absolute_path)))
    if errors:
        raise ConfigError(f"{where}: config {_key(errors[0])}")
    try:
        _check_data(sub)
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    return sub


def _check_data(cfg: dict) -> None:
    """The region and source checks the schema cannot express: bbox and time order, and the
    file or URL each source kind needs."""
    bbox = cfg["region"]["bbox"]
    if not bbox["west"] < bbox["east"]:
        raise ConfigError("config key 'region.bbox': west must be less than east "
                          f"(got west={bbox['west']}, east={bbox['east']}; "
                          "longitudes are -180..180)")
    if not bbox["south"] < bbox["north"]:
        raise ConfigError("config key 'region.bbox': south must be less than north "
                          f"(got south={bbox['south']}, north={bbox['north']})")
    t0, t1 = (datetime.fromisoformat(cfg["region"]["time"][k]) for k in ("start", "end"))
    if not t0 < t1:
        raise ConfigError("config key 'region.time': start must be before end "
                          f"(got {cfg['region']['time']['start']} .. {cfg['region']['time']['end']})")
    src = cfg["sources"]
    needs = {
        ("currents", "files"): ("files", "currents"),
        ("bathymetry", "files"): ("files", "bathymetry"),
        ("bathymetry", "etopo"): ("etopo", "path"),
    }
    for (layer, kind), (sec, key) in needs.items():
        if src[layer] == kind and not cfg[sec][key]:
            raise ConfigError(f"config key '{sec}.{key}' is required when sources.{layer} is "
                              f"'{kind}'")
    if src["bathymetry"] == "gebco" and not (cfg["gebco"]["path"] or cfg["gebco"]["url"]):
        raise ConfigError("config key 'gebco.path' or 'gebco.url' is required when "
                          "sources.bathymetry is 'gebco'")
    if src["tides"] and src["currents"] == "files" and not cfg["files"]["tides"]:
        raise ConfigError("config key 'files.tides' is required when sources.tides is true and "
                          "sources.currents is 'files' (or set sources.tides: false)")


def _check_scenes(cfg: dict) -> None:
    """Every ``scenes.list`` entry is a valid scene spec (the scene builder's own check, so a
    typo fails before any job runs), names are unique folder names, and ``scenes.compare``
    and ``rollouts.scene`` (when its backend is mujoco) name a listed scene."""
    import re

    from .backends.mujoco.scenes import normalise_spec

    sc = cfg["scenes"]
    names = []
    for i, spec in enumerate(sc["list"]):
        try:
            names.append(normalise_spec(spec)["name"])
        except ConfigError as exc:
            raise ConfigError(f"config key 'scenes.list[{i}]': {exc}") from None
        if not re.fullmatch(r"[A-Za-z0-9_-]+", names[-1]):
            raise ConfigError(f"config key 'scenes.list[{i}].name': {names[-1]!r} must be "
                              "letters, digits, '_' or '-' (it names a folder)")
    if len(set(names)) != len(names):
        raise ConfigError(f"config key 'scenes.list': duplicate scene name in {names}")
    if sc["compare"] not in names:
        raise ConfigError(f"config key 'scenes.compare': {sc['compare']!r} is not a scene of "
                          f"scenes.list ({', '.join(names)})")
    r = cfg["rollouts"]
    if r["backend"] == "mujoco" and r["scene"] not in names:
        raise ConfigError(f"config key 'rollouts.scene': {r['scene']!r} is not a scene of "
                          f"scenes.list ({', '.join(names)})")


def llm_method(model: dict) -> str:
    """The method name of an ``llm.models`` entry.

    Parameters
    ----------
    model : dict
        An ``llm.models`` entry (its ``name`` is used).

    Returns
    -------
    str
        ``llm_<name>``.
    """
    return f"llm_{model['name']}"


def register_llm_methods(cfg: dict) -> list[str]:
    """Register one ``planner`` method per ``llm.models`` entry, so paths, wildcards and tables
    know them.

    A method already registered under the name is kept as it is.

    Parameters
    ----------
    cfg : dict
        The config (its ``llm.models``; a missing or empty ``llm`` registers nothing).

    Returns
    -------
    list of str
        The methods' names, ``llm_<name>`` (:func:`llm_method`), in ``llm.models`` order.
    """
    out = []
    for m in (cfg.get("llm") or {}).get("models") or []:
        name = llm_method(m)
        if name not in registry.method_names():
            registry.register_method(registry.MethodSpec(
                name, m.get("label") or f"LLM-{m['name']}", "planner",
                "the heuristic's information (plan inputs summarised as text)",
                f"LLM planner {m.get('model') or m.get('model_path')}: every K steps an "
                "assignment from the model, validated, else the heuristic's plan; the "
                "heuristic's low-level control.", short=m.get("label") or f"LLM-{m['name']}"))
        out.append(name)
    return out


def _check_held_out(rollouts: dict) -> None:
    """The evaluation seed must not be a calibration seed of any task it evaluates."""
    from .tasks.tiers import load_task_table

    seed = int(rollouts["seed"])
    rep = rollouts.get("replicate") or {}
    reps = [int(s) for s in rep.get("seeds", [])]
    if seed in reps:
        raise ConfigError(f"config key 'rollouts.replicate.seeds': {seed} is the evaluation "
                          "seed rollouts.seed; a replicate needs other episodes")
    from . import registry

    for m in rep.get("methods", []):
        if m == "bc" or m not in registry.method_names():
            raise ConfigError(f"config key 'rollouts.replicate.methods': {m!r} is not a "
                              "replicable method (one of rollouts.methods' fused methods; bc "
                              "is not replicated)")
    for task in rollouts["tasks"]:
        cal = [int(s) for s in (load_task_table(task).get("calibration") or {}).get("seeds", [])]
        for key, s in [("rollouts.seed", seed)] + [("rollouts.replicate.seeds", r)
                                                   for r in reps]:
            if s in cal:
                raise ConfigError(f"config key '{key}': {s} is a calibration seed of task "
                                  f"{task} (its tier table's calibration.seeds {cal}); "
                                  "evaluate on held-out seeds")


def load_config(*paths: str | Path, overrides: dict | None = None) -> dict:
    """Deep-merge YAML files (later wins) and ``overrides``, then validate.

    Parameters
    ----------
    *paths : str or pathlib.Path
        Config YAML files, each a mapping at the top level (an empty file is an empty one).
    overrides : dict, optional
        Merged last, over the files.

    Returns
    -------
    dict
        The validated config, defaults filled (:func:`validate_config`).

    Raises
    ------
    ConfigError
        A file is missing, not valid YAML or not a mapping, or the merged config is invalid.
    """
    merged: dict = {}
    for p in paths:
        try:
            with open(p) as fh:
                data = yaml.safe_load(fh) or {}
        except FileNotFoundError:
            raise ConfigError(f"config file {p}: not found") from None
        except yaml.YAMLError as exc:
            raise ConfigError(f"config file {p}: not valid YAML ({exc.__class__.__name__})") from None
        if not isinstance(data, dict):
            raise ConfigError(f"config file {p}: top level must be a mapping")
        deep_update(merged, data)
    if overrides:
        deep_update(merged, overrides)
    return validate_config(merged)


def deep_update(base: dict, new: dict) -> dict:
    """Merge ``new`` into ``base`` recursively: mappings merge, anything else replaces.

    Parameters
    ----------
    base : dict
        The mapping to update, in place.
    new : dict
        The values that win; copied deeply into ``base``.

    Returns
    -------
    dict
        ``base``.
    """
    for k, v in new.items():
        if isinstance(v, dict) and isinstance(base.get(k), dict):
            deep_update(base[k], v)
        else:
            base[k] = copy.deepcopy(v)
    return base
