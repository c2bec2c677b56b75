"""The package list: the fixed packages, then every technique folder (a folder with an
__init__.py under techniques/), so a new technique needs no edit here. Everything else is in
pyproject.toml."""
from pathlib import Path

from setuptools import setup

HERE = Path(__file__).resolve().parent
FIXED = ["inshade", "inshade.bench", "inshade.convert", "inshade.codegen", "inshade.models", "inshade.runtime", "inshade.scene", "inshade.geometry",
         "inshade.viewer", "inshade.shaders", "inshade.techniques", "inshade.web"]
TECHNIQUES = sorted(f"inshade.techniques.{d.name}" for d in (HERE / "techniques").iterdir()
                    if (d / "__init__.py").is_file())

setup(packages=FIXED + TECHNIQUES)
