"""One batch through a generated network on the compute device (see the package docstring)."""
from __future__ import annotations

import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from inshade.bundle import UINT_INPUT_RANGE
from inshade.codegen.glsl import (StorageBufferResource, TextureResource, UniformBlockResource, blocks,
                                  resource_bindings)

from .device import ShaderBuildError, compute_device
from .slangc import compile_spirv
from .textures import sampler_entries, texture_layout, texture_view

HERE = Path(__file__).resolve().parent
WORKGROUP = 64
MAX_GROUPS = 65535      # per dispatch dimension; the harness reads a second dimension past it
# the harnesses of the languages with a preprocessor read the uint inputs (xu) under #ifdef NET_IN_UINT_BLOCKS
UINT_HARNESS = {"wgsl": "eval_uint.wgsl"}


def spirv(source: str, args: list[str]) -> bytes:
    """SPIR-V of a GLSL or HLSL compute shader, by glslangValidator."""
    exe = shutil.which("glslangValidator")
    if exe is None:
        raise ShaderBuildError("glslangValidator is needed for the vulkan and hlsl targets (Debian: glslang-tools)")
    with tempfile.TemporaryDirectory() as tmp:
        src, out = Path(tmp) / "net.comp", Path(tmp) / "net.spv"
        src.write_text(source)
        run = subprocess.run([exe, *args, str(src), "-o", str(out)], capture_output=True, text=True)
        if run.returncode != 0:
            raise ShaderBuildError(f"glslangValidator {' '.join(args)}: " + (run.stdout + run.stderr).strip())
        return out.read_bytes()


def batch_arrays(generated, x) -> tuple[np.ndarray, np.ndarray | None]:
    """A batch [N, in_dim] as the harness reads it: the float lanes padded to whole blocks, and the uint
    lanes (a bundle's uint inputs, given as exact float integers as torch takes them) as uint32 blocks,
    or None when the network has none."""
    x = np.asarray(x, np.float32).reshape(len(x), -1)
    if x.shape[1] != generated.in_dim:
        raise ValueError(f"inputs must be [N, {generated.in_dim}], got {list(x.shape)}")
    uint = np.zeros(generated.in_dim, bool)
    uint[list(generated.uint_lanes)] = True
    floats = np.zeros((len(x), generated.in_blocks * 4), np.float32)
    floats[:, :generated.float_in_dim] = x[:, ~uint]
    if not uint.any():
        return floats, None
    ids = x[:, uint]
    if (ids < 0).any() or (ids >= UINT_INPUT_RANGE).any() or (ids != np.floor(ids)).any():
        raise ValueError(f"uint inputs must be integers in 0..{UINT_INPUT_RANGE - 1}")
    uints = np.zeros((len(x), generated.in_uint_blocks * 4), np.uint32)
    uints[:, :ids.shape[1]] = ids.astype(np.uint32)
    return floats, uints


def slang_spirv(source: str) -> bytes:
    """SPIR-V of a Slang compute shader, by the Slang compiler slangpy ships."""
    try:
        return compile_spirv(source)
    except RuntimeError as exc:
        raise ShaderBuildError(str(exc)) from None


# how each target's source becomes a shader module: (harness, compiler, or None for WGSL, which wgpu
# takes as it is). Slang reads the HLSL harness.
SOURCES = {
    "wgsl": ("eval.wgsl", None),
    "vulkan": ("eval.vulkan.glsl", lambda source: spirv("#version 450\n" + source, ["-V", "-S", "comp"])),
    "hlsl": ("eval.hlsl", lambda source: spirv(source, ["-D", "-V", "-S", "comp", "-e", "main"])),
    "slang": ("eval.hlsl", slang_spirv),
}


def shader_code(generated, target: str):
    """The module wgpu takes: WGSL text, or SPIR-V bytes compiled from GLSL / HLSL / Slang."""
    if generated.prefix != "net":
        raise ValueError(f"the batch harness calls net_eval: generate with prefix 'net' (got {generated.prefix!r})")
    if target not in SOURCES:
        raise ValueError(f"no compute driver for target {target!r} (drivers: {', '.join(SOURCES)})")
    harness, compiler = SOURCES[target]
    if generated.uint_lanes:   # WGSL has no preprocessor: a harness of its own reads the uint inputs
        harness = UINT_HARNESS.get(target, harness)
    source = generated.chunk + "\n" + (HERE / harness).read_text()
    return source if compiler is None else compiler(source)


def _resource_entries(dev, generated) -> list[tuple[dict, dict]]:
    """(layout entry, bind-group entry) of each resource and sampler of the network, at the plan's bindings."""
    wgpu, device = dev.wgpu, dev.device
    bindings = resource_bindings(generated.resources)
    entries = []
    for r in generated.resources:
        if isinstance(r, (UniformBlockResource, StorageBufferResource)):
            uniform = isinstance(r, UniformBlockResource)
            buf = device.create_buffer_with_data(data=r.data, usage=wgpu.BufferUsage.UNIFORM if uniform
                                                 else wgpu.BufferUsage.STORAGE)
            layout = {"buffer": {"type": "uniform" if uniform else "read-only-storage"}}
            resource = {"buffer": buf, "offset": 0, "size": len(r.data)}
        elif isinstance(r, TextureResource):
            layout, resource = texture_layout(r), texture_view(dev, r)
        else:
            raise ValueError(f"resource {r.name}: {type(r).__name__} has no compute-driver binding")
        entries.append(({"binding": bindings[r.name], **layout}, {"binding": bindings[r.name], "resource": resource}))
    return entries + sampler_entries(dev, generated.resources, bindings)


def _bind_group(device, wgpu, entries: list[tuple[dict, dict]]):
    """A bind group and its layout declaring every entry, read by the code or not (a compiler drops what
    the code never reads, so a layout taken from the code would not match what the host binds)."""
    layout = device.create_bind_group_layout(entries=[{**e, "visibility": wgpu.ShaderStage.COMPUTE}
                                                      for e, _ in entries])
    return layout, device.create_bind_group(layout=layout, entries=[b for _, b in entries])


class Dispatch:
    """A network's pipeline and a batch bound to it: ``run()`` computes (and waits), ``read()`` reads back;
    ``compile_s`` is what making the shader module and the pipeline took."""

    def __init__(self, generated, x: np.ndarray, target: str, code=None):
        dev = compute_device()
        wgpu, device = dev.wgpu, dev.device
        padded, uints = batch_arrays(generated, x)
        self.n, self.out_dim, self.out_blocks = len(padded), generated.out_dim, blocks(generated.out_dim)
        code = shader_code(generated, target) if code is None else code
        xin = device.create_buffer_with_data(data=padded.tobytes(), usage=wgpu.BufferUsage.STORAGE)
        self.yout = device.create_buffer(size=max(16, self.n * self.out_blocks * 16),
                                         usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC)
        batch = [(0, "read-only-storage", xin), (1, "storage", self.yout)]
        if uints is not None:
            batch.append((2, "read-only-storage", device.create_buffer_with_data(data=uints.tobytes(),
                                                                                 usage=wgpu.BufferUsage.STORAGE)))
        layouts, self.groups = zip(
            _bind_group(device, wgpu, _resource_entries(dev, generated)),
            _bind_group(device, wgpu, [({"binding": b, "buffer": {"type": kind}}, {"binding": b, "resource": {"buffer": buf}})
                                       for b, kind, buf in batch]))
        start = time.perf_counter()
        module = device.create_shader_module(code=code)
        self.pipeline = device.create_compute_pipeline(
            layout=device.create_pipeline_layout(bind_group_layouts=list(layouts)),
            compute={"module": module, "entry_point": "main"})
        self.compile_s = time.perf_counter() - start
        self.fence = device.create_buffer(size=16, usage=wgpu.BufferUsage.COPY_SRC)
        self.device = device

    def run(self) -> None:
        encoder = self.device.create_command_encoder()
        compute = encoder.begin_compute_pass()
        compute.set_pipeline(self.pipeline)
        for i, group in enumerate(self.groups):
            compute.set_bind_group(i, group)
        total = -(-self.n // WORKGROUP)
        compute.dispatch_workgroups(min(total, MAX_GROUPS), -(-total // MAX_GROUPS), 1)
        compute.end()
        self.device.queue.submit([encoder.finish()])
        # reading a 16-byte buffer queued after the dispatch waits for it (wgpu-py 0.32's
        # on_submitted_work_done_sync fails on wgpu-native's callback signature)
        self.device.queue.read_buffer(self.fence)

    def read(self) -> np.ndarray:
        y = np.frombuffer(self.device.queue.read_buffer(self.yout), np.float32)[: self.n * self.out_blocks * 4]
        return y.reshape(self.n, self.out_blocks * 4)[:, :self.out_dim].copy()


def evaluate(generated, x: np.ndarray, target: str, code=None) -> np.ndarray:
    """The network's outputs [N, out_dim] for inputs x [N, in_dim], computed by ``generated`` (made
    for ``target``) on the compute device; ``code``: a shader module of the caller's around the same
    network and harness (an engine drop-in's), instead of the target's own."""
    run = Dispatch(generated, x, target, code)
    run.run()
    return run.read()
