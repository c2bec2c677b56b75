"""One batch through a generated network on the compute device (see the package docstring)."""
from __future__ import annotations

import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from inshade.codegen.glsl import TextureResource, UniformBlockResource, blocks

from .device import compute_device

HERE = Path(__file__).resolve().parent
WORKGROUP = 64
MAX_GROUPS = 65535      # per dispatch dimension; the harness reads a second dimension past it
# texels as wgpu names their formats: (moderngl dtype, channels) -> format
TEXTURE_FORMATS = {("f4", 4): "rgba32float", ("f2", 4): "rgba16float", ("f4", 1): "r32float",
                   ("f4", 2): "rg32float", ("f2", 1): "r16float", ("f2", 2): "rg16float"}
# how each target's source becomes a shader module: (harness, compiler arguments or None for WGSL)
SOURCES = {
    "wgsl": ("eval.wgsl", None),
    "vulkan": ("eval.vulkan.glsl", ["-V", "-S", "comp"]),
    "hlsl": ("eval.hlsl", ["-D", "-V", "-S", "comp", "-e", "main"]),
}


class ShaderBuildError(RuntimeError):
    """A generated source its language's compiler refused (the compiler's log attached)."""


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


def shader_code(generated, target: str):
    """The module wgpu takes: WGSL text, or SPIR-V bytes compiled from GLSL / HLSL."""
    if generated.prefix != "net":
        raise ValueError(f"the batch harness calls net_eval: generate with prefix 'net' (got {generated.prefix!r})")
    if target not in SOURCES:
        raise ValueError(f"no compute driver for target {target!r} (drivers: {', '.join(SOURCES)})")
    harness, args = SOURCES[target]
    source = generated.chunk + "\n" + (HERE / harness).read_text()
    if args is None:
        return source
    return spirv(("#version 450\n" if target == "vulkan" else "") + source, args)


def _resource_entries(dev, generated) -> list[dict]:
    wgpu, device = dev.wgpu, dev.device
    entries = []
    for binding, r in enumerate(generated.resources):
        if isinstance(r, UniformBlockResource):
            buf = device.create_buffer_with_data(data=r.data, usage=wgpu.BufferUsage.UNIFORM)
            entries.append({"binding": binding, "resource": {"buffer": buf, "offset": 0, "size": len(r.data)}})
        elif isinstance(r, TextureResource) and r.dims == 2 and not r.array and not r.mips:
            data = np.ascontiguousarray(r.data)
            h, w, c = data.shape
            fmt = TEXTURE_FORMATS.get((r.dtype, c))
            if fmt is None:
                raise ValueError(f"texture {r.name}: {r.dtype} x {c} has no compute-driver format yet")
            tex = device.create_texture(size=(w, h, 1), format=fmt,
                                        usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST)
            device.queue.write_texture({"texture": tex}, data.tobytes(), {"bytes_per_row": w * data.itemsize * c,
                                                                          "rows_per_image": h}, (w, h, 1))
            entries.append({"binding": binding, "resource": tex.create_view()})
        else:
            raise ValueError(f"resource {r.name}: only uniform blocks and plain 2D textures run on the compute driver yet")
    return entries


class Dispatch:
    """A network's pipeline and a batch bound to it: ``run()`` computes (and waits), ``read()`` reads back;
    ``compile_s`` is what making the shader module and the pipeline took."""

    def __init__(self, generated, x: np.ndarray, target: str):
        dev = compute_device()
        wgpu, device = dev.wgpu, dev.device
        x = np.asarray(x, np.float32).reshape(len(x), -1)
        self.n, self.out_dim, self.out_blocks = len(x), generated.out_dim, blocks(generated.out_dim)
        padded = np.zeros((self.n, generated.in_blocks * 4), np.float32)
        padded[:, :x.shape[1]] = x
        code = shader_code(generated, target)
        start = time.perf_counter()
        module = device.create_shader_module(code=code)
        self.pipeline = device.create_compute_pipeline(layout="auto", compute={"module": module, "entry_point": "main"})
        self.compile_s = time.perf_counter() - start
        xin = device.create_buffer_with_data(data=padded.tobytes(), usage=wgpu.BufferUsage.STORAGE)
        self.yout = device.create_buffer(size=max(16, self.n * self.out_blocks * 16),
                                         usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC)
        self.groups = [
            device.create_bind_group(layout=self.pipeline.get_bind_group_layout(0),
                                     entries=_resource_entries(dev, generated)),
            device.create_bind_group(layout=self.pipeline.get_bind_group_layout(1), entries=[
                {"binding": 0, "resource": {"buffer": xin}}, {"binding": 1, "resource": {"buffer": self.yout}}])]
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


def evaluate(generated, x: np.ndarray, target: str) -> np.ndarray:
    """The network's outputs [N, out_dim] for inputs x [N, in_dim], computed by ``generated`` (made
    for ``target``) on the compute device."""
    run = Dispatch(generated, x, target)
    run.run()
    return run.read()
