"""The float targets a renderer draws into, and the passes around the scene pass: the running mean
of an accumulating program's samples, and the depth-peeled BLEND surfaces of a glTF mesh."""
from __future__ import annotations

from typing import Callable

import moderngl

from .programs import ProgramCache
from .render import FullscreenPass, float_target, release_target
from .scene_program import VERTEX

BLEND_LAYERS = 4      # BLEND surfaces peeled per pixel: a fifth one behind four others is not drawn
BLEND_LAYER_READS = ("uv", "uv_grad", "uv1", "uv1_dy")   # a layer's G-buffer targets passes/gltf_blend_layer reads


class RenderTargets(dict):
    """Float targets by name ("network", "output", ...), each remade only when its size or number
    of attachments changes."""

    def __init__(self, ctx: moderngl.Context):
        super().__init__()
        self.ctx = ctx

    def target(self, name: str, width: int, height: int, attachments: int = 1) -> moderngl.Framebuffer:
        fbo = self.get(name)
        if fbo is not None and fbo.size == (width, height) and len(fbo.color_attachments) == attachments:
            return fbo
        if fbo is not None:
            release_target(fbo)
        fbo = self[name] = float_target(self.ctx, width, height, attachments=attachments)
        return fbo

    def release(self) -> None:
        for fbo in self.values():
            release_target(fbo)
        self.clear()


class Accumulation:
    """passes/accumulate.frag: folds one more sample into the running mean of every attachment."""

    def __init__(self, ctx: moderngl.Context, cache: ProgramCache, version: str, attachments: int):
        self.attachments = attachments
        program = cache.get(VERTEX, "passes/accumulate.frag", version=version,
                            defines={"ACCUMULATE_ATTACHMENTS": attachments})
        self.pass_ = FullscreenPass(ctx, program)

    @property
    def program(self) -> moderngl.Program:
        return self.pass_.program

    def fold(self, targets: RenderTargets, sample: moderngl.Framebuffer, width: int, height: int,
             count: int) -> moderngl.Framebuffer:
        """"network" (the mean of ``count`` - 1 samples) + ``sample`` -> the spare target, which then
        becomes "network" (ping-pong: a pass cannot read its own target)."""
        n = self.attachments
        mean = targets.target("network", width, height, n)
        spare = targets.target("network_spare", width, height, n)
        textures = {}
        for k in range(n):
            textures[f"u_mean{k}"] = mean.color_attachments[k]
            textures[f"u_sample{k}"] = sample.color_attachments[k]
        self.pass_.render(spare, uniforms={"u_count": count}, textures=textures)
        targets["network"], targets["network_spare"] = spare, mean
        return spare

    def release(self) -> None:
        self.pass_.vao.release()


class BlendPeel:
    """The BLEND surfaces of a glTF mesh, depth-peeled front to back (MeshGBuffer.draw_layer), each
    layer shaded by the scene program and laid under the ones in front (passes/gltf_blend_layer),
    then the whole over the opaque surfaces (passes/gltf_blend_resolve)."""

    def __init__(self, ctx: moderngl.Context, cache: ProgramCache, gbuffer_defines: dict):
        self.layer_pass, self.resolve_pass = (
            FullscreenPass(ctx, cache.get(VERTEX, f"passes/{name}.frag", defines=gbuffer_defines or None))
            for name in ("gltf_blend_layer", "gltf_blend_resolve"))

    def draw(self, targets: RenderTargets, camera, width: int, height: int, *, gbuffer, layers: int,
             material_textures: dict, shade: Callable, opaque: moderngl.Framebuffer,
             out: moderngl.Framebuffer) -> None:
        """``layers`` layers over ``opaque`` into ``out``; ``shade(layer, into)`` draws the scene
        program over one layer's G-buffer textures."""
        accum = [targets.target("blend_accum_a", width, height), targets.target("blend_accum_b", width, height)]
        accum[0].clear(0.0, 0.0, 0.0, 1.0)
        shaded = targets.target("blend_layer", width, height)
        view, proj = camera.view_matrix(), camera.projection(width, height)
        read = [n for n in gbuffer.names if n in BLEND_LAYER_READS]   # u_layer_<name>
        for k in range(1, layers + 1):
            layer = gbuffer.draw_layer(k, view, proj, None, width, height)
            shade(layer, shaded)
            src, dst = accum[(k - 1) % 2], accum[k % 2]
            self.layer_pass.render(dst, textures={**material_textures, "u_accum": src.color_attachments[0],
                                                  "u_layer_colour": shaded.color_attachments[0],
                                                  **{f"u_layer_{n}": layer[gbuffer.names.index(n)] for n in read}})
        self.resolve_pass.render(out, textures={"u_accum": accum[layers % 2].color_attachments[0],
                                                "u_opaque": opaque.color_attachments[0]})

    def release(self) -> None:
        for p in (self.layer_pass, self.resolve_pass):
            p.vao.release()
