"""What travels with the installed package: the shipped configs by name, the version, ``python -m``,
and the wheel's contents."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
import yaml

import hier_ssl
from hier_ssl import cli
from hier_ssl.config import ConfigError
from hier_ssl.config.files import config_dir, config_names, find_config, load_yaml
from hier_ssl.envs import load_config

ROOT = Path(__file__).parents[1]
SHIPPED = sorted(
    p.relative_to(ROOT / "configs").with_suffix("").as_posix() for p in ROOT.glob("configs/**/*.yaml")
)


def test_every_yaml_under_configs_is_a_shipped_name() -> None:
    assert config_dir().resolve() == (ROOT / "configs").resolve()  # a checkout reads its own directory
    assert config_names() == SHIPPED and "proposed/fscaps" in SHIPPED and "scenarios/crowd" in SHIPPED


def test_names_resolve_from_any_directory(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    shipped = (ROOT / "configs" / "proposed" / "fscaps.yaml").resolve()
    for name in ("proposed/fscaps", "proposed/fscaps.yaml", "configs/proposed/fscaps.yaml"):
        assert find_config(name) == shipped, name
    assert load_config("obstacle/fscaps") == load_config(ROOT / "configs" / "obstacle" / "fscaps.yaml")
    assert hier_ssl.parallel_env(config="obstacle/fscaps").config.task == "obstacle"
    # A file in the current directory wins over the shipped config of the same name.
    (tmp_path / "proposed").mkdir()
    (tmp_path / "proposed" / "fscaps.yaml").write_text("name: mine\n")
    assert load_config("proposed/fscaps.yaml").name == "mine"
    for bad in ("proposed/nope", "fscaps", str(tmp_path / "missing.yaml")):
        with pytest.raises(ConfigError, match="config file not found"):
            find_config(bad)


def test_a_config_with_a_base_holds_only_its_changes(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "mid.yaml").write_text("base: paper/baseline/fscaps\nname: mid\nsac:\n  gamma: 0.9\n")
    (tmp_path / "top.yaml").write_text("base: sub/mid.yaml\nname: top\ntotal_steps: 70000\n")
    paper = load_yaml("paper/baseline/fscaps")
    top = load_yaml(tmp_path / "top.yaml")
    # Sections merge key by key down the chain; the file's own keys win; nothing else changes.
    assert top == {**paper, "name": "top", "total_steps": 70000, "sac": {**paper["sac"], "gamma": 0.9}}
    assert load_config(tmp_path / "top.yaml").sac.reward_scale == 1.0
    (tmp_path / "loop.yaml").write_text("base: sub/loop2.yaml\n")
    (tmp_path / "sub" / "loop2.yaml").write_text("base: ../loop.yaml\n")
    with pytest.raises(ConfigError, match="loop2.yaml: base: '../loop.yaml' includes itself"):
        load_yaml(tmp_path / "loop.yaml")
    (tmp_path / "bad.yaml").write_text("base: nowhere/nothing\n")
    with pytest.raises(ConfigError, match="bad.yaml: base: config file not found: nowhere/nothing"):
        load_yaml(tmp_path / "bad.yaml")
    (tmp_path / "list.yaml").write_text("base: [a, b]\n")
    with pytest.raises(ConfigError, match=r"list.yaml: base: expected .*\['a', 'b'\]"):
        load_yaml(tmp_path / "list.yaml")


def _run(*argv: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, *argv], cwd=cwd, capture_output=True, text=True, env=os.environ)


def test_train_by_name_from_another_directory_reaches_validation(tmp_path: Path) -> None:
    # The bad override proves the shipped config was found and parsed; nothing is trained or written.
    done = _run("-m", "hier_ssl", "train", "proposed/fscaps", "--set", "env.frame_skp=4", cwd=tmp_path)
    assert done.returncode == 1 and "env.frame_skp" in done.stderr and "not found" not in done.stderr
    assert list(tmp_path.iterdir()) == []


def test_configs_command_lists_names_descriptions_and_the_directory(
    capsys: pytest.CaptureFixture[str],
) -> None:
    # Each file says what it trains in its own words: a variant does not inherit its base's description.
    own = {name: yaml.safe_load((ROOT / "configs" / f"{name}.yaml").read_text()) for name in SHIPPED}
    descriptions = {name: data.get("description") for name, data in own.items()}
    assert all(descriptions.values()) and len(set(descriptions.values())) == len(SHIPPED)
    assert cli.main(["configs"]) == 0
    listed = [line.split(None, 1) for line in capsys.readouterr().out.splitlines()]
    assert listed == [[name, descriptions[name]] for name in SHIPPED]
    assert cli.main(["configs", "--dir"]) == 0
    assert Path(capsys.readouterr().out.strip()) == config_dir()


def test_a_description_is_one_short_line() -> None:
    from hier_ssl.envs import parse_config

    assert parse_config({"description": "Proposed task, SAC"}).description == "Proposed task, SAC"
    for bad in ("two\nlines", "x" * 101):
        with pytest.raises(ConfigError, match="description"):
            parse_config({"description": bad})


def test_version_and_python_dash_m(tmp_path: Path) -> None:
    done = _run("-m", "hier_ssl", "--version", cwd=tmp_path)
    assert done.returncode == 0 and done.stdout.strip() == f"hier-ssl {hier_ssl.__version__}"
    done = _run("-m", "hier_ssl", "configs", cwd=tmp_path)
    assert done.returncode == 0 and [line.split()[0] for line in done.stdout.splitlines()] == SHIPPED


def test_the_wheel_ships_configs_and_py_typed_and_finds_them_installed(tmp_path: Path) -> None:
    pytest.importorskip("setuptools", minversion="68")
    # Built from a copy, so the build leaves nothing in the checkout.
    source = tmp_path / "src"
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for name in ("hier_ssl", "configs"):
        shutil.copytree(ROOT / name, source / name, ignore=ignore)
    for name in ("pyproject.toml", "setup.py", "README.md"):
        shutil.copy(ROOT / name, source / name)
    pip = [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", "dist", "."]
    done = subprocess.run(pip, cwd=source, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    (wheel,) = (source / "dist").glob("hier_ssl-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert "hier_ssl/py.typed" in names and "hier_ssl/__main__.py" in names
    assert {f"hier_ssl/configs/{name}.yaml" for name in SHIPPED} <= names
    assert not any(name.startswith("configs/") for name in names)  # inside the package, not beside it

    # Unpacked as pip installs it, away from any checkout: the names resolve inside the package.
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    probe = "from hier_ssl.config.files import *; print(config_dir()); print(find_config('proposed/fscaps'))"
    done = subprocess.run(
        [sys.executable, "-c", probe],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(site)},
    )
    assert done.returncode == 0, done.stderr
    where, found = map(Path, done.stdout.split())
    assert where == site / "hier_ssl" / "configs" and found == where / "proposed" / "fscaps.yaml"
