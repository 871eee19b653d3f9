"""Config files: finding the shipped ones, reading YAML, applying ``--set key=value`` overrides.

What the files hold is checked by ``hier_ssl.config`` (the models) and ``hier_ssl.envs.parse_config``.
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import yaml

from hier_ssl.config.schema import ConfigError


def apply_overrides(data: dict[str, Any], overrides: list[str]) -> dict[str, Any]:
    """``key.sub=value`` strings applied to a copy of ``data``; values are parsed as YAML scalars."""
    data = copy.deepcopy(data)
    for item in overrides:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise ConfigError(f"--set {item!r}: expected key=value")
        node = data
        *parents, leaf = key.split(".")
        for part in parents:
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                raise ConfigError(f"--set {key}: {part!r} is not a section")
            node = child
        node[leaf] = yaml.safe_load(raw)
    return data


def config_dir() -> Path:
    """The shipped configs: ``hier_ssl/configs`` in an installed wheel (setup.py maps the repository's
    ``configs/`` there), else the ``configs/`` beside the package in a checkout or editable install."""
    package = Path(__file__).resolve().parents[1]
    installed = package / "configs"
    return installed if installed.is_dir() else package.parent / "configs"


def config_names() -> list[str]:
    """Names of the shipped configs, e.g. ``proposed/fscaps`` for ``configs/proposed/fscaps.yaml``."""
    root = config_dir()
    return sorted(p.relative_to(root).with_suffix("").as_posix() for p in root.rglob("*.yaml"))


def find_config(path: str | Path) -> Path:
    """``path`` if it is a file, else the shipped config it names: ``proposed/fscaps``, with or without
    ``.yaml``, or the checkout's path ``configs/proposed/fscaps.yaml``; ConfigError when it is neither."""
    path = Path(path)
    if path.is_file():
        return path
    name = path.as_posix().removeprefix("configs/").removesuffix(".yaml")
    root = config_dir().resolve()
    shipped = (root / f"{name}.yaml").resolve()
    if not path.is_absolute() and shipped.is_relative_to(root) and shipped.is_file():
        return shipped
    raise ConfigError(f"config file not found: {path} (nor a shipped config: `hier-ssl configs` lists them)")


def _merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """``over`` on top of ``base``: sections merge key by key, any other value replaces the base's."""
    out = copy.deepcopy(base)
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def load_yaml(path: str | Path, _seen: tuple[Path, ...] = ()) -> dict[str, Any]:
    """The mapping in the YAML file ``path`` (or the shipped config it names, ``find_config``).

    A file with ``base: OTHER`` holds only what it changes: it is read on top of OTHER (a path relative to
    the file, or a shipped name such as ``paper/baseline/fscaps``), so a variant of a config names its
    differences instead of copying the rest."""
    path = find_config(path)
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as err:
        raise ConfigError(f"{path}: not valid YAML ({err})") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: top level must be a mapping, got {type(data).__name__}")
    if "base" not in data:
        return data
    name = data.pop("base")
    if not isinstance(name, str):
        raise ConfigError(f"{path}: base: expected a config file or shipped name, got {name!r}")
    beside = path.parent / name
    try:
        base = find_config(beside if beside.is_file() else name).resolve()
    except ConfigError as err:
        raise ConfigError(f"{path}: base: {err}") from None
    if base in (path.resolve(), *_seen):
        raise ConfigError(f"{path}: base: {name!r} includes itself")
    return _merge(load_yaml(base, (*_seen, path.resolve())), data)
