"""Configuration: load, validate against the workflow's JSON schemas, fill defaults.

The schemas live in ``workflow/schemas/`` (``config.schema.yaml`` for the top level,
one ``<study>.schema.yaml`` per study, referenced from it). The Snakefile and library
users go through the same :func:`validate`, so a bad config is rejected with the same
message whether it reaches Snakemake or Python::

    >>> from granpipe import config
    >>> cfg = config.load("config/quick.yaml")          # doctest: +SKIP
    >>> cfg["drum"]["physics"]["dt"]                    # doctest: +SKIP

A rejected config raises :class:`granpipe.errors.ConfigError` whose message names
the key (dotted path, e.g. ``drum.physics.dt``) and the expected form.
"""

from __future__ import annotations

import copy
import functools
import importlib
import math
import os
from collections.abc import Mapping
from pathlib import Path

import yaml

from .errors import ConfigError

__all__ = [
    "schema_dir",
    "load",
    "read_yaml",
    "read_schema",
    "validate",
    "validate_params",
    "study_section",
    "fill_defaults",
    "STUDIES",
    "MAX_SIMULATION_JOBS",
    "check_plan",
    "check_memory",
    "machine_memory",
]

STUDIES = ("drum", "column", "box", "shear")


def schema_dir() -> Path:
    """Folder of the JSON schemas (``workflow/schemas`` of the source tree).

    ``GRANPIPE_SCHEMA_DIR`` overrides it (for an installed copy without the tree).
    """
    env = os.environ.get("GRANPIPE_SCHEMA_DIR")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[2] / "workflow" / "schemas"


# libyaml's parser where PyYAML was built with it (the same documents, ~10x faster)
_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def read_schema(path: str | os.PathLike) -> dict:
    """The schema file ``path`` parsed (a fresh copy), read once per file version: every
    validation of a config or of a stage's ``--params`` reads the schemas, and parsing
    them anew took ~1 s per validation in pure-Python YAML."""
    path = Path(path).resolve()
    st = path.stat()
    return copy.deepcopy(_parsed_schema(path, st.st_mtime_ns, st.st_size))


@functools.lru_cache(maxsize=16)
def _parsed_schema(path: Path, mtime_ns: int, size: int) -> dict:
    return yaml.load(path.read_text(), Loader=_SAFE_LOADER)  # noqa: S506 - a safe loader


def _key(path) -> str:
    parts = [str(p) if not isinstance(p, int) else f"[{p}]" for p in path]
    return ".".join(parts).replace(".[", "[") or "<top level>"


def _expected(schema: Mapping) -> str:
    """A short human description of what a schema accepts."""
    bits = []
    if "enum" in schema:
        bits.append("one of " + ", ".join(repr(v) for v in schema["enum"]))
    if "type" in schema:
        t = schema["type"]
        bits.append(t if isinstance(t, str) else " or ".join(t))
    for word, sym in (
        ("exclusiveMinimum", ">"),
        ("minimum", ">="),
        ("exclusiveMaximum", "<"),
        ("maximum", "<="),
    ):
        if word in schema:
            bits.append(f"{sym} {schema[word]}")
    if "minItems" in schema:
        bits.append(f"at least {schema['minItems']} item(s)")
    if "pattern" in schema:
        bits.append(f"matching {schema['pattern']}")
    if "description" in schema:
        bits.append(f"({schema['description'].strip()})")
    return " ".join(bits) or "see config/README.md"


def _message(err) -> str:
    path = list(err.absolute_path)
    if err.validator == "additionalProperties":
        allowed = sorted(err.schema.get("properties", {}))
        extra = sorted(set(err.instance) - set(allowed))
        keys = ", ".join(repr(_key([*path, k])) for k in extra)
        return f"unknown config key {keys}; allowed keys under '{_key(path)}': " + (
            ", ".join(allowed) if allowed else "none"
        )
    if err.validator == "required":
        missing = err.message.split("'")[1] if "'" in err.message else err.message
        return f"missing config key '{_key([*path, missing])}'"
    message = err.message.replace(repr(err.instance), _short(err.instance))
    return (
        f"config key '{_key(path)}' = {_short(err.instance)} is invalid: {message}; "
        f"expected {_expected(err.schema)}"
    )


@functools.lru_cache(maxsize=8)
def _validator(schema_file: Path, mtimes: tuple):
    """A Draft 2020-12 validator of ``schema_file`` with its sibling ``$ref`` files
    (cached per file set and modification times)."""
    import jsonschema
    from referencing import Registry, Resource

    schema = read_schema(schema_file)
    base = schema_file.parent

    def retrieve(uri: str):
        return Resource.from_contents(read_schema(base / uri.rsplit("/", 1)[-1]))

    schema["$id"] = schema_file.as_uri()
    registry = Registry(retrieve=retrieve).with_resource(
        schema["$id"], Resource.from_contents(schema)
    )
    return jsonschema.Draft202012Validator(schema, registry=registry)


def _innermost(err):
    """The error to report from a combinator (``anyOf``/``oneOf``): the one of the branch
    the value's type fits (a number against ``number or array`` is judged as a number),
    descending to the innermost key; jsonschema's own choice may report another branch's
    type ("0 is not of type 'array'")."""
    import jsonschema

    while err.context:
        branches: dict = {}
        for sub in err.context:
            branches.setdefault(sub.relative_schema_path[0], []).append(sub)
        fitting = [
            errs for errs in branches.values()
            if not any(e.validator == "type" and not e.relative_path for e in errs)
        ]  # fmt: skip
        candidates = fitting[0] if len(fitting) == 1 else list(err.context)
        best = jsonschema.exceptions.best_match(candidates)
        if best is None or best is err:
            break
        err = best
    return err


def fill_defaults(instance, schema: Mapping, root: Mapping, base: Path | None = None):
    """Set the schema's defaults in ``instance`` in place (objects and their properties,
    recursively), following ``$ref`` to ``#/...`` pointers of ``root`` and to sibling
    schema files in ``base``; return ``instance``. Snakemake's validator fills the top
    level only, not through the study schemas' references."""
    while "$ref" in schema:
        ref = schema["$ref"]
        rest = {k: v for k, v in schema.items() if k != "$ref"}
        if ref.startswith("#/"):
            target = root
            for part in ref[2:].split("/"):
                target = target[part]
        elif base is not None:
            target = root = read_schema(base / ref)
        else:
            raise ValueError(f"unsupported $ref {ref}")
        schema = {**target, **rest}
    if isinstance(instance, dict) and "properties" in schema:
        for key, sub in schema["properties"].items():
            if key not in instance and "default" in sub:
                instance[key] = copy.deepcopy(sub["default"])
            if key in instance:
                fill_defaults(instance[key], sub, root, base)
    return instance


def _check_with_jsonschema(cfg: Mapping, schema_file: Path) -> None:
    """Collect every violation with its key path (clearer than the first error alone)."""

    schema_file = schema_file.resolve()
    mtimes = tuple(p.stat().st_mtime_ns for p in sorted(schema_file.parent.glob("*.yaml")))
    validator = _validator(schema_file, mtimes)
    errors = sorted(validator.iter_errors(cfg), key=lambda e: list(map(str, e.absolute_path)))
    leaf = list(dict.fromkeys(_message(_innermost(err)) for err in errors))
    if len(leaf) > MAX_REPORTED:
        leaf = [*leaf[:MAX_REPORTED], f"... and {len(leaf) - MAX_REPORTED} more"]
    if leaf:
        raise ConfigError("invalid configuration:\n  - " + "\n  - ".join(leaf))


MAX_INTEGER = 2**63 - 1
"""The largest integer a config may hold: a count or seed beyond it has no 64-bit
integer, and a 400-digit number overflows a float."""


def _non_finite(obj, path=()) -> list[str]:
    """Dotted keys whose value is NaN or ±inf, or an integer beyond :data:`MAX_INTEGER`
    (they pass every schema bound)."""
    if isinstance(obj, Mapping):
        return [k for key, v in obj.items() for k in _non_finite(v, (*path, key))]
    if isinstance(obj, list | tuple):
        return [k for i, v in enumerate(obj) for k in _non_finite(v, (*path, i))]
    if isinstance(obj, float) and not math.isfinite(obj):
        return [f"'{_key(path)}' = {obj!r}"]
    if isinstance(obj, int) and not isinstance(obj, bool) and abs(obj) > MAX_INTEGER:
        return [f"'{_key(path)}' = {_short(obj)} (beyond ±{MAX_INTEGER})"]
    return []


MAX_SIMULATION_JOBS = 10_000
"""The most simulation jobs (init, runs, batches, points) one study's config may ask for.
Snakemake's planning time grows with the number of jobs: the paper scale (2,939 jobs over
the three studies, 1,560 of them the drum's) plans in 17 s, ~6 ms per job, so 10,000 jobs
take about a minute before anything runs. The limit also keeps every batch and replica
index inside the rules' four-digit patterns (a drum batch is two jobs, a box replica at
least two, a column batch one, beside the two continuum jobs); the box's three-digit part
numbers are checked on their own."""


def check_plan(key: str, jobs: int, remedy: str) -> None:
    """Refuse a study that asks for more than :data:`MAX_SIMULATION_JOBS` simulation jobs,
    naming the key and the remedy."""
    if jobs > MAX_SIMULATION_JOBS:
        raise ConfigError(
            f"config key '{key}': {jobs} simulation jobs, more than {MAX_SIMULATION_JOBS} "
            f"(Snakemake would take over a minute to plan them): {remedy}"
        )


def machine_memory() -> int | None:
    """Bytes of physical memory of this machine (None where the system does not say)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(key: str, value, need: float) -> None:
    """Refuse a size whose job would need more memory (``need`` bytes, the study's
    estimate) than this machine has, naming the key."""
    total = machine_memory()
    if total is not None and need > total:
        raise ConfigError(
            f"config key '{key}' = {_short(value)}: one job would need about "
            f"{need / 1e9:.3g} GB of memory, more than this machine's {total / 1e9:.3g} GB"
        )


MAX_REPORTED = 10
"""The most violations one error lists (a list of 10,000 bad values is not echoed)."""

MAX_SCALE_LENGTH = 64
"""The longest scale name (one folder of the results tree)."""

MAX_RESULTS_LENGTH = 1024
"""The longest results root: with the scale, the study, a point's folder and a file name
below it, a path stays well under the 4096 bytes of Linux's PATH_MAX."""


def _check_paths(cfg: Mapping) -> None:
    """``scale`` and ``results`` keep every output inside ``<results>/<scale>/``, below the
    working directory: the scale one folder name (not ``.`` or ``..``), the results root a
    relative path without ``..`` and not the working directory itself, neither too long
    nor holding control characters. ConfigError names the key."""
    scale, results = cfg.get("scale"), cfg.get("results")
    if isinstance(scale, str):
        if scale in (".", ".."):
            raise ConfigError(
                f"config key 'scale' = {scale!r} is not a folder name: outputs would land "
                "outside <results>/<scale>/"
            )
        if len(scale) > MAX_SCALE_LENGTH:
            raise ConfigError(
                f"config key 'scale' is {len(scale)} characters long, more than {MAX_SCALE_LENGTH}"
            )
    if not isinstance(results, str) or not results:
        return
    path = Path(results)
    if path.is_absolute():
        raise ConfigError(
            f"config key 'results' = {_short(results)} must be relative to the working "
            "directory (a symbolic link there can point elsewhere)"
        )
    if ".." in path.parts:
        raise ConfigError(
            f"config key 'results' = {_short(results)} climbs out of the working directory ('..')"
        )
    if not path.parts:  # "." or "./"
        raise ConfigError(
            f"config key 'results' = {_short(results)} is the working directory itself: "
            "name a folder below it (e.g. results)"
        )
    if any(ord(c) < 32 or ord(c) == 127 for c in results):
        raise ConfigError(f"config key 'results' = {_short(results)} holds a control character")
    if len(results.encode()) > MAX_RESULTS_LENGTH or any(
        len(part.encode()) > 255 for part in path.parts
    ):
        raise ConfigError(
            f"config key 'results' is too long ({len(results.encode())} bytes; at most "
            f"{MAX_RESULTS_LENGTH}, and 255 per folder name)"
        )
    if path.exists() and not path.is_dir():
        raise ConfigError(f"config key 'results' = {_short(results)} is an existing file, not a "
                          "folder")  # fmt: skip


def _short(value, limit: int = 80) -> str:
    """``repr(value)``, cut to ``limit`` characters (a value that YAML aliases expand can
    be megabytes long)."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[: limit - 20]}... ({len(text)} characters)"


STUDY_CHECKS = {
    "drum": "granpipe.drum.layout",
    "column": "granpipe.column.layout",
    "box": "granpipe.box.layout",
    "shear": "granpipe.shear.layout",
}
"""Modules whose ``check(section)`` makes the cross-key checks of a study's section (fit
windows inside the recorded window, min ≤ max, selections inside the grid, ...)."""


def validate(cfg: dict, schema_file: str | os.PathLike | None = None) -> dict:
    """Validate ``cfg`` in place against the schemas, filling defaults; return it.

    Refuses NaN and ±inf anywhere, then validates against the JSON schemas (Draft
    2020-12, every violation reported with its dotted key path), fills the schemas'
    defaults through their references (:func:`fill_defaults`; Snakemake's own validator
    fills the top level only, and a second pass through it added nothing on any shipped
    config), then runs each listed study's cross-key checks (:data:`STUDY_CHECKS`). The
    Snakefile and ``granpipe check-config`` both call this.

    Raises
    ------
    ConfigError
        naming each offending key and the expected form.
    """
    if not isinstance(cfg, dict):
        raise ConfigError(f"a config must be a mapping of keys, got {type(cfg).__name__}")
    bad = _non_finite(cfg)
    if bad:
        raise ConfigError(
            f"invalid configuration: not a finite number within ±{MAX_INTEGER}: "
            + ", ".join(bad[:MAX_REPORTED])
        )
    schema_file = Path(schema_file) if schema_file else schema_dir() / "config.schema.yaml"
    _check_with_jsonschema(cfg, schema_file)
    _check_paths(cfg)
    schema = read_schema(schema_file)
    fill_defaults(cfg, schema, schema, schema_file.resolve().parent)
    for study in cfg.get("studies", []):
        if study in STUDY_CHECKS and study in cfg:
            importlib.import_module(STUDY_CHECKS[study]).check(cfg[study])
    return cfg


def validate_params(
    params: Mapping,
    study: str,
    refs: Mapping[str, str] | None = None,
    extra: Mapping[str, Mapping] | None = None,
    required=None,
    fill: bool = True,
) -> dict:
    """Validate a stage's ``--params`` (a config subset a rule passes) before the stage
    runs, and return a copy with the schema's defaults filled in (``fill``; else the
    params as they are).

    ``refs`` maps each key of the subset to the JSON pointer of its schema in
    ``<study>.schema.yaml`` (e.g. ``{"physics": "/properties/physics"}``), ``extra`` to a
    schema of its own (keys the study schema does not have: a point's name, the config
    hashes of the inputs); ``required`` (default: every key of both) must be present.

    Raises
    ------
    ConfigError
        naming ``--params`` and each offending key, as :func:`validate` does.
    """
    import jsonschema

    bad = _non_finite(dict(params))
    if bad:
        raise ConfigError(f"--params: not a finite number within ±{MAX_INTEGER}: " + bad[0])
    refs, extra = dict(refs or {}), dict(extra or {})
    root = read_schema(schema_dir() / f"{study}.schema.yaml")
    props = {k: {"$ref": f"#/x-study{ptr}"} for k, ptr in refs.items()}
    props.update(extra)
    schema = {
        "$defs": root.get("$defs", {}),
        "x-study": root,
        "type": "object",
        "required": sorted(props if required is None else required),
        "properties": props,
    }
    errors = sorted(
        jsonschema.Draft202012Validator(schema).iter_errors(dict(params)),
        key=lambda e: list(map(str, e.absolute_path)),
    )
    if errors:
        text = _message(_innermost(errors[0])).replace("config key", "--params key", 1)
        raise ConfigError(text.replace("missing --params key", "--params lacks the key", 1))
    out = copy.deepcopy(dict(params))
    return fill_defaults(out, schema, schema) if fill else out


class _StrictLoader(yaml.SafeLoader):
    """A YAML loader that refuses a key given twice in one mapping, naming its line."""


def _no_duplicates(loader, node, deep=False):
    seen = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None,
                f"duplicate key {key!r} (first on line {seen[key] + 1})",
                key_node.start_mark,
            )  # fmt: skip
        seen[key] = key_node.start_mark.line
    return loader.construct_mapping(node, deep=deep)


_StrictLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _no_duplicates)


def read_yaml(path: str | os.PathLike):
    """Read a YAML file strictly (no duplicate keys); errors name the file and line."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ConfigError(f"config file not found: {path}") from None
    except IsADirectoryError:
        raise ConfigError(f"config file {path} is a folder, not a YAML file") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"config file {path} is not a text (UTF-8) file: byte {exc.start} is not text"
        ) from None
    except OSError as exc:
        raise ConfigError(f"cannot read config file {path}: {exc.strerror}") from None
    try:
        value = yaml.load(text, Loader=_StrictLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"{path}, line {mark.line + 1}, column {mark.column + 1}" if mark else str(path)
        what = exc.problem or str(exc)
        raise ConfigError(f"config file {where} is not valid YAML: {what}") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"config file {path} is not valid YAML: {exc}") from None
    if _expanded_size(value, {}, MAX_VALUES) > MAX_VALUES:
        raise ConfigError(
            f"config file {path} expands (through YAML aliases) to more than {MAX_VALUES} values"
        )
    return value


MAX_VALUES = 1_000_000
"""The most values (mappings, lists and scalars) a config file may expand to: YAML
aliases let a few lines stand for billions of values."""


def _expanded_size(obj, memo: dict, limit: int) -> int:
    """The number of values ``obj`` stands for once its aliases are expanded (each shared
    object counted once per use, computed once), stopping above ``limit``."""
    key = id(obj)
    if key in memo:
        return memo[key]
    n = 1
    if isinstance(obj, Mapping):
        children = list(obj.values())
    elif isinstance(obj, list):
        children = obj
    else:
        children = []
    for child in children:
        n += _expanded_size(child, memo, limit)
        if n > limit:
            break
    memo[key] = n
    return n


def load(path: str | os.PathLike) -> dict:
    """Read a YAML config file, validate it, fill defaults, and return it."""
    cfg = read_yaml(path)
    if cfg is None:
        raise ConfigError(f"config file {path} is empty")
    return validate(cfg)


def study_section(cfg: Mapping, study: str) -> dict:
    """A deep copy of one study's section of a validated config."""
    if study not in STUDIES:
        raise ConfigError(f"unknown study '{study}'; known: {', '.join(STUDIES)}")
    if study not in cfg:
        raise ConfigError(f"config has no '{study}' section (studies: {cfg.get('studies')})")
    return copy.deepcopy(cfg[study])
