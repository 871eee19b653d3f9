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


def load_yaml(path: str | Path) -> dict[str, Any]:
    """The mapping in the YAML file ``path`` (or the shipped config it names, ``find_config``)."""
    path = find_config(path)
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as err:
        raise ConfigError(f"{path}: not valid YAML ({err})") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: top level must be a mapping, got {type(data).__name__}")
    return data
