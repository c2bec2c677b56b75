"""Which optional extra brings a missing module: one line instead of a traceback when a runtime-only
install (``pip install -e .``) meets a command that needs more (``inshade view`` needs imgui-bundle,
``inshade bench mlp`` and ``inshade train`` need torch, ``inshade convert`` needs onnx)."""
from __future__ import annotations

import re

# import name -> distribution name, where they differ
DISTRIBUTIONS = {"skimage": "scikit-image", "imgui_bundle": "imgui-bundle", "astc_encoder": "astc-encoder-py",
                 "flip_evaluator": "flip-evaluator", "point_cloud_utils": "point-cloud-utils",
                 "fast_simplification": "fast-simplification", "OpenGL": "PyOpenGL", "PIL": "pillow"}
# the extra each command would name first when several bring the module
PREFERRED = {"view": "view", "bench": "bench", "train": "train", "convert": "onnx", "eval": "onnx"}
_REQUIREMENT = re.compile(r"^\s*([A-Za-z0-9_.\-]+)[^;]*;\s*extra\s*==\s*['\"]([^'\"]+)['\"]")


def extras_of(distribution: str) -> list[str]:
    """The extras of the installed inshade that list ``distribution`` (in pyproject order)."""
    from importlib import metadata

    try:
        requires = metadata.requires("inshade") or []
    except metadata.PackageNotFoundError:
        return []
    found = []
    for line in requires:
        m = _REQUIREMENT.match(line)
        if m and m.group(1).lower().replace("_", "-") == distribution.lower() and m.group(2) != "test":
            found.append(m.group(2))
    return found


def missing_line(module: str, command: str | None) -> str:
    """'inshade COMMAND needs DIST (not installed): pip install -e '.[EXTRA]'' for a missing module."""
    top = module.split(".")[0]
    dist = DISTRIBUTIONS.get(top, top)
    extras = extras_of(dist)
    what = f"inshade {command}" if command else "this command"
    if not extras:
        return f"{what} needs the module {top} ({dist}), which is not installed"
    preferred = PREFERRED.get((command or "").split(" ")[0])
    extra = preferred if preferred in extras else extras[0]
    return f"{what} needs {dist} (not installed): pip install -e '.[{extra}]'"
