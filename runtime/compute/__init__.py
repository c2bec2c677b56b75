"""Networks generated for WebGPU, Vulkan, Direct3D and Slang, evaluated on a real driver: one compute
invocation per element of a batch calls the generated eval function, through wgpu-native (PyPI
``wgpu``) on whatever Vulkan device the machine has (Mesa's lavapipe on a CPU).

- ``wgsl``: the module as WebGPU takes it.
- ``vulkan``: GLSL 4.50 compiled to SPIR-V by glslangValidator (``-V``).
- ``hlsl``: compiled to SPIR-V by glslang's HLSL front end (``-D``).
- ``slang``: compiled to SPIR-V by the Slang compiler slangpy ships (runtime/compute/slangc.py).

The batch harness of each language (``eval.*`` beside this file; Slang reads the HLSL one) binds the
inputs and outputs in group / set / space 1; the network's own resources stay where the plan put them
(0). Optional: ``pip install 'inshade[compute]'``.
"""
from __future__ import annotations

from .device import ComputeDevice, ComputeUnavailable, ShaderBuildError, compute_device
from .run import SOURCES, Dispatch, evaluate

TARGETS = tuple(SOURCES)


def prepare(generated, x, target: str):
    """A network generated for ``target`` compiled, with the batch x bound: ``.run()``, ``.read()``,
    ``.compile_s``."""
    return Dispatch(generated, x, target)


def device_name(target: str) -> str:
    """The device that runs ``target``'s code here."""
    return compute_device().description


def run_target(generated, x, target: str):
    """(outputs [N, out_dim], the device that computed them) of a network generated for ``target``."""
    run = prepare(generated, x, target)
    run.run()
    return run.read(), device_name(target)


__all__ = ["TARGETS", "SOURCES", "ComputeDevice", "ComputeUnavailable", "ShaderBuildError", "Dispatch", "compute_device",
           "device_name", "evaluate", "prepare", "run_target"]
