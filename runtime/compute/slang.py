"""Slang: the module compiled by the Slang compiler slangpy ships and run by slangpy.

slangpy 0.43 opens no Vulkan or WebGPU device on Mesa's lavapipe ("Failed to create device"), so
on a machine without a GPU the module runs on slangpy's CPU device (Slang compiled to host code);
with a GPU, slangpy's default device runs it. Either way the Slang compiler reads the very module
``inshade codegen --target slang`` writes."""
from __future__ import annotations

import hashlib
import importlib
import time
from functools import lru_cache
from pathlib import Path

import numpy as np

from inshade.codegen.glsl import StorageBufferResource, TextureResource, UniformBlockResource, blocks

from .device import ComputeUnavailable
from .run import batch_arrays

HARNESS = Path(__file__).resolve().parent / "eval.slang"
INSTALL_HINT = "pip install slangpy"
ENTRY = "inshade_eval"


@lru_cache(maxsize=1)
def slang_device():
    """slangpy's device: the default one where it opens, else its CPU device."""
    try:
        spy = importlib.import_module("slangpy")
    except ImportError as e:
        raise ComputeUnavailable(f"the slang target runs through slangpy: {INSTALL_HINT}") from e
    try:
        return spy, spy.Device(type=spy.DeviceType.automatic)
    except RuntimeError:
        logger = spy.Logger.get()
        level, logger.level = logger.level, spy.LogLevel.error   # its "no shader model" warning: noise here
        try:
            return spy, spy.Device(type=spy.DeviceType.cpu)
        finally:
            logger.level = level


def device_name() -> str:
    spy, device = slang_device()
    return f"{device.info.adapter_name} (slangpy {device.info.type.name})"


def _uniform_vars(resource: UniformBlockResource) -> dict:
    """A std140 block's arrays as the values slangpy writes into the module's constant buffer (a
    mat4 as its 4 columns, which the module reads as rows: it declares the matrix row_major)."""
    data, at, members = np.frombuffer(resource.data, np.float32), 0, {}
    for type_, name, count in resource.members:
        shape = {"mat4": (4, 4), "vec4": (4,)}[type_]
        size = int(np.prod(shape))
        members[name] = [np.array(a) for a in data[at: at + count * size].reshape(count, *shape)]
        at += count * size
    return {resource.instance: members}


class SlangDispatch:
    """The module compiled and a batch bound to it (``run()``, ``read()``, ``compile_s``: as
    runtime.compute.run.Dispatch)."""

    def __init__(self, generated, x: np.ndarray):
        spy, device = slang_device()
        padded, uints = batch_arrays(generated, x)
        self.n, self.out_dim, self.out_blocks = len(padded), generated.out_dim, blocks(generated.out_dim)
        source = generated.chunk + "\n" + HARNESS.read_text()
        # a session keeps each module by name: one name per source
        name = "inshade_" + hashlib.sha256(source.encode()).hexdigest()[:16]
        start = time.perf_counter()
        module = device.load_module_from_source(name, source)
        self.kernel = device.create_compute_kernel(device.link_program([module], [module.entry_point(ENTRY)]))
        self.compile_s = time.perf_counter() - start
        for r in generated.resources:
            # slangpy 0.43's CPU device reads back garbage from every texture it makes (its own to_numpy
            # too): the module compiled, it cannot run here
            if isinstance(r, TextureResource) and device.info.type.name == "cpu":
                raise ValueError(f"resource {r.name}: slangpy's CPU device cannot upload textures; run the slang "
                                 "target with storage 'inline', 'ubo' or 'ssbo' here")
        xin = device.create_buffer(data=padded, struct_size=16, usage=spy.BufferUsage.shader_resource)
        self.yout = device.create_buffer(element_count=self.n * self.out_blocks, struct_size=16,
                                         usage=spy.BufferUsage.unordered_access)
        self.values = {"inshade_x": xin, "inshade_y": self.yout}
        if uints is not None:
            self.values["inshade_xu"] = device.create_buffer(data=uints, struct_size=16,
                                                             usage=spy.BufferUsage.shader_resource)
        for r in generated.resources:
            if isinstance(r, StorageBufferResource):   # a structured buffer of one element (the block's bytes)
                self.values[f"{r.instance}_buffer"] = device.create_buffer(
                    data=np.frombuffer(r.data, np.uint8).copy(), struct_size=len(r.data), usage=spy.BufferUsage.shader_resource)
            else:
                self.values.update(_uniform_vars(r))
        self.device = device

    def run(self) -> None:
        self.kernel.dispatch(thread_count=[self.n, 1, 1], vars=self.values)
        self.device.wait()

    def read(self) -> np.ndarray:
        y = self.yout.to_numpy().view(np.float32).reshape(self.n, self.out_blocks * 4)
        return y[:, :self.out_dim].copy()


def evaluate_slang(generated, x: np.ndarray) -> np.ndarray:
    """Outputs [N, out_dim] of a network generated for the slang target, for inputs x [N, in_dim]."""
    run = SlangDispatch(generated, x)
    run.run()
    return run.read()
