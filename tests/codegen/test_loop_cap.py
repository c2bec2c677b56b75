"""A network evaluated many times per pixel (a sphere tracer's steps) on a driver that caps a
pixel's loop iterations (llvmpipe: 65535, shared by every loop): the dense loops unroll enough that
every evaluation runs, and the sum over the caller's loop matches torch."""
from __future__ import annotations

import moderngl
import numpy as np
import pytest
import torch

import inshade
from inshade.bundle import load
from inshade.codegen.limits import LimitError, loop_iteration_cap
from inshade.codegen.network import generate
from inshade.components.dense import emit_plan
from inshade.components.dense.emit_plan import loop_chunks
from inshade.runtime.context import gl_info
from inshade.runtime.network import NetworkResources
from inshade.shaders import assemble

from parity import assert_parity

# 1700 evaluations x 40 iterations over the first layer's outputs = 68000 > 65535 (the last
# layer's 40 input blocks are written out, not looped over)
CALLS = 1700
PIXELS = 32

CALLER = """
#include <network>
out vec4 o;
void main() {
    float px = floor(gl_FragCoord.x);
    float total = 0.0;
    for (int k = 0; k < CALLS; ++k) {   // each step a new input: nothing to hoist out of the loop
        vec4 x[1];
        x[0] = vec4(px / float(PIXELS), float(k) * 0.001, 0.0, 0.0);
        vec4 y[1];
        net_eval(x, y);
        total += y[0].x;
    }
    o = vec4(total, 0.0, 0.0, 1.0);
}
"""


def deep_net() -> torch.nn.Sequential:
    torch.manual_seed(5)
    return torch.nn.Sequential(torch.nn.Linear(2, 160), torch.nn.Tanh(), torch.nn.Linear(160, 1)).eval()


def deep_bundle(folder):
    inshade.export(deep_net(), torch.rand(8, 2), folder, check=False, quiet=True)
    return load(folder)


def test_a_network_in_a_long_loop_runs_every_evaluation(gl, tmp_path):
    net, bundle = deep_net(), deep_bundle(tmp_path / "b")
    limits = gl_info(gl)
    gen = generate(bundle, storage="texture", limits=limits, calls=CALLS)
    looped = [r for r in gen.plan.rows if r.type == "dense" and r.storage == "texture"]
    cap = loop_iteration_cap(limits)
    if cap is not None:   # the plan says which layers unrolled, and why
        assert any("ends a pixel's loops after" in r.why for r in looped)
    source = assemble("caller", version="330", defines={"CALLS": CALLS, "PIXELS": PIXELS},
                      chunks={"caller": CALLER, "network": gen.chunk}).source
    vertex = assemble("common/fullscreen.vert", version="330").source
    program = gl.program(vertex_shader=vertex, fragment_shader=source)
    resources = NetworkResources(gl, gen)
    target = gl.texture((PIXELS, 1), 4, dtype="f4")
    fbo = gl.framebuffer([target])
    try:
        resources.bind(program)
        fbo.use()
        gl.vertex_array(program, []).render(moderngl.TRIANGLES, vertices=3)
        got = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(PIXELS, 4)[:, 0]
    finally:
        for obj in (fbo, target, program):
            obj.release()
        resources.release()
    px, k = np.meshgrid(np.arange(PIXELS, dtype=np.float32), np.arange(CALLS, dtype=np.float32), indexing="ij")
    x = np.stack([px / np.float32(PIXELS), k * np.float32(0.001)], -1).reshape(-1, 2)
    with torch.no_grad():
        y = net(torch.from_numpy(x)).numpy().reshape(PIXELS, CALLS)
    assert_parity(got, y.sum(1, dtype=np.float64).astype(np.float32), tol=1e-5 * CALLS,
                  what=f"a 160-wide network evaluated {CALLS} times per pixel")


def test_the_budget_unrolls_only_what_it_needs(tmp_path, monkeypatch):
    bundle = deep_bundle(tmp_path / "b")
    storage = {n.id: ("texture", "") for n in bundle.nodes if n.type == "dense"}
    llvmpipe = {"renderer": "llvmpipe (LLVM 15.0.6, 256 bits)"}
    assert [c for c, _ in loop_chunks(bundle, storage, {"renderer": "NVIDIA H200"}, CALLS).values()] == [1, 1]
    assert [c for c, _ in loop_chunks(bundle, storage, llvmpipe, 1).values()] == [1, 1]
    assert [c for c, _ in loop_chunks(bundle, storage, llvmpipe, CALLS).values()] == [2, 1]
    monkeypatch.setattr(emit_plan, "INPUTS_WRITTEN_MAX", 8)   # the last layer's 40 input blocks looped over
    with pytest.raises(LimitError, match=r"exceed this driver's 65535 .*fewer march steps"):
        loop_chunks(bundle, storage, llvmpipe, 2000)   # 40 inputs a pass is the floor: 2000 x 40 > 65535


def test_codegen_says_which_layer_unrolled_for_the_callers_loop(gl, tmp_path, capsys):
    from inshade.cli import main

    deep_bundle(tmp_path / "b")
    assert main(["codegen", str(tmp_path / "b"), "--storage", "texture", "--calls", str(CALLS)]) == 0
    report = capsys.readouterr().out
    if loop_iteration_cap(gl_info(gl)) is not None:
        assert "unrolled x2: this driver ends a pixel's loops after 65535 iterations in all" in report
    with pytest.raises(SystemExit):
        main(["codegen", str(tmp_path / "b"), "--calls", "0"])
    assert "--calls: must be >= 1, got 0" in capsys.readouterr().err
