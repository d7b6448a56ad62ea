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

__all__ = ["schema_dir", "load", "read_yaml", "validate", "study_section", "STUDIES"]

STUDIES = ("drum", "column", "box")


def schema_dir() -> Path:
    """Folder of the JSON schemas (``workflow/schemas`` of the source tree).

    ``GRANPIPE_SCHEMA_DIR`` overrides it (for an installed copy without the tree).
    """
    env = os.environ.get("GRANPIPE_SCHEMA_DIR")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[2] / "workflow" / "schemas"


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
    return (
        f"config key '{_key(path)}' = {err.instance!r} is invalid: {err.message}; "
        f"expected {_expected(err.schema)}"
    )


@functools.lru_cache(maxsize=8)
def _validator(schema_file: Path, mtimes: tuple):
    """A Draft 2020-12 validator of ``schema_file`` with its sibling ``$ref`` files
    (cached per file set and modification times)."""
    import jsonschema
    from referencing import Registry, Resource

    schema = yaml.safe_load(schema_file.read_text())
    base = schema_file.parent

    def retrieve(uri: str):
        name = uri.rsplit("/", 1)[-1]
        return Resource.from_contents(yaml.safe_load((base / name).read_text()))

    schema["$id"] = schema_file.as_uri()
    registry = Registry(retrieve=retrieve).with_resource(
        schema["$id"], Resource.from_contents(schema)
    )
    return jsonschema.Draft202012Validator(schema, registry=registry)


def _check_with_jsonschema(cfg: Mapping, schema_file: Path) -> None:
    """Collect every violation with its key path (clearer than the first error alone)."""
    import jsonschema

    schema_file = schema_file.resolve()
    mtimes = tuple(p.stat().st_mtime_ns for p in sorted(schema_file.parent.glob("*.yaml")))
    validator = _validator(schema_file, mtimes)
    errors = sorted(validator.iter_errors(cfg), key=lambda e: list(map(str, e.absolute_path)))
    leaf = []
    for err in errors:
        # Descend into combinators so the message names the innermost key.
        best = jsonschema.exceptions.best_match([err, *err.context]) if err.context else err
        leaf.append(_message(best))
    if leaf:
        raise ConfigError("invalid configuration:\n  - " + "\n  - ".join(dict.fromkeys(leaf)))


def _non_finite(obj, path=()) -> list[str]:
    """Dotted keys whose value is NaN or ±inf (they pass every schema bound)."""
    if isinstance(obj, Mapping):
        return [k for key, v in obj.items() for k in _non_finite(v, (*path, key))]
    if isinstance(obj, list | tuple):
        return [k for i, v in enumerate(obj) for k in _non_finite(v, (*path, i))]
    if isinstance(obj, float) and not math.isfinite(obj):
        return [f"'{_key(path)}' = {obj!r}"]
    return []


STUDY_CHECKS = {
    "drum": "granpipe.drum.layout",
    "column": "granpipe.column.layout",
    "box": "granpipe.box.layout",
}
"""Modules whose ``check(section)`` makes the cross-key checks of a study's section (fit
windows inside the recorded window, min ≤ max, selections inside the grid, ...)."""


def validate(cfg: dict, schema_file: str | os.PathLike | None = None) -> dict:
    """Validate ``cfg`` in place against the schemas, filling defaults; return it.

    Refuses NaN and ±inf anywhere, then uses :func:`snakemake.utils.validate` (which
    fills schema defaults) after a first pass that reports every violation with its
    dotted key path, then each listed study's cross-key checks (:data:`STUDY_CHECKS`).
    The Snakefile and ``granpipe check-config`` both call this.

    Raises
    ------
    ConfigError
        naming each offending key and the expected form.
    """
    if not isinstance(cfg, dict):
        raise ConfigError(f"a config must be a mapping of keys, got {type(cfg).__name__}")
    bad = _non_finite(cfg)
    if bad:
        raise ConfigError("invalid configuration: not a finite number: " + ", ".join(bad))
    schema_file = Path(schema_file) if schema_file else schema_dir() / "config.schema.yaml"
    _check_with_jsonschema(cfg, schema_file)
    from snakemake.exceptions import WorkflowError
    from snakemake.utils import validate as smk_validate

    try:
        smk_validate(cfg, str(schema_file.resolve()), set_default=True)
    except WorkflowError as exc:  # pragma: no cover - the first pass catches these
        raise ConfigError(str(exc)) from exc
    for study in cfg.get("studies", []):
        if study in STUDY_CHECKS and study in cfg:
            importlib.import_module(STUDY_CHECKS[study]).check(cfg[study])
    return cfg


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
    except OSError as exc:
        raise ConfigError(f"cannot read config file {path}: {exc.strerror}") from None
    try:
        return yaml.load(text, Loader=_StrictLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"{path}, line {mark.line + 1}, column {mark.column + 1}" if mark else str(path)
        what = exc.problem or str(exc)
        raise ConfigError(f"config file {where} is not valid YAML: {what}") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"config file {path} is not valid YAML: {exc}") from None


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
