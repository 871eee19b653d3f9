"""Package layout that pyproject.toml cannot state: the repository's top-level ``configs/`` ships inside
the package as ``hier_ssl/configs`` (read by ``hier_ssl.config.files.config_dir``), so an installed
``hier-ssl train proposed/fscaps`` finds its config from any directory. Everything else is in
pyproject.toml."""

from setuptools import find_namespace_packages, setup

setup(
    packages=[*find_namespace_packages(include=["hier_ssl", "hier_ssl.*"]), "hier_ssl.configs"],
    package_dir={"hier_ssl.configs": "configs"},
    package_data={"hier_ssl": ["py.typed"], "hier_ssl.configs": ["**/*.yaml"]},
)
