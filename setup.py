"""The package list: the fixed packages, then every component folder and every technique folder (a
folder with an __init__.py under components/ or techniques/), so a new one needs no edit here. Everything else is in
pyproject.toml."""
from pathlib import Path

from setuptools import setup

HERE = Path(__file__).resolve().parent
FIXED = ["inshade", "inshade.commands", "inshade.engines", "inshade.bench", "inshade.convert", "inshade.convert.ops",
         "inshade.convert.tcnn_encodings", "inshade.codegen", "inshade.codegen.printers",
         "inshade.components", "inshade.runtime.compute",
         "inshade.models",
         "inshade.runtime", "inshade.scene", "inshade.geometry", "inshade.viewer", "inshade.shaders", "inshade.techniques",
         "inshade.web"]
COMPONENTS = sorted(f"inshade.components.{d.name}" for d in (HERE / "components").iterdir()
                    if (d / "__init__.py").is_file())
TECHNIQUES = sorted(f"inshade.techniques.{d.name}" for d in (HERE / "techniques").iterdir()
                    if (d / "__init__.py").is_file())
# The GLSL folders and the web page's folder are data packages (their files ship through
# package-data): listed, so the build neither skips nor warns about them.
SHADER_ROOTS = [("inshade.shaders", HERE / "shaders")] + [
    (f"{t}.shaders", HERE / "techniques" / t.rsplit(".", 1)[1] / "shaders") for t in TECHNIQUES]
SHADER_FOLDERS = sorted({
    ".".join([name, *d.relative_to(root).parts])
    for name, root in SHADER_ROOTS if root.is_dir()
    for d in [root, *root.rglob("*")] if d.is_dir() and any(d.glob("*.glsl")) and d != HERE / "shaders"})

setup(packages=FIXED + COMPONENTS + TECHNIQUES + SHADER_FOLDERS + ["inshade.web.page"])
