// The viewer's passes on WebGPU: the same passes, programs and data as GLBackend (inshade.js), the
// programs as export-web translated them to WGSL (web/webgpu.py): each texture split into a texture
// and a sampler (bound as <uniform>_image, <uniform>_sampler), loose uniforms in one uniform buffer per
// stage at the offsets the manifest lists, the fragment stage in bind group 0 and the vertex stage in 1.
// Texel rows are GL's: the vertex stage's y is flipped, so row 0 of every target is GL's bottom row;
// only the canvas runs top down (yDown), which the present pass reads bottom up.

import { UNORM16, WebGPUError, uploadTexture } from "./webgpu.js";

const TARGET_FORMATS = {rgba32f: "rgba32float", rg32f: "rg32float", r32f: "r32float", r32ui: "r32uint"};
const FRAME = "rgba8unorm";       // the canvas's format: 8-bit values the present pass encoded as sRGB
const DEPTH = "depth24plus";      // GL's DEPTH_COMPONENT24
const VIEWS = {"2d": "2d", "3d": "3d", "2d_array": "2d-array"};
// limits the page asks for up to what the adapter has: a G-buffer writes several float targets at once
const LIMITS = ["maxColorAttachments", "maxColorAttachmentBytesPerSample", "maxSampledTexturesPerShaderStage",
                "maxSamplersPerShaderStage", "maxUniformBufferBindingSize", "maxTextureDimension2D",
                "maxTextureDimension3D", "maxTextureArrayLayers", "maxBindingsPerBindGroup"];
const USAGE = () => GPUTextureUsage.TEXTURE_BINDING | GPUTextureUsage.COPY_DST;
const nextFrame = () => new Promise((resolve) => requestAnimationFrame(resolve));

export class WebGPUBackend {
  static async create(canvas, {manifest, sources}, progress = () => {}) {
    if (!navigator.gpu) throw new WebGPUError("this browser has no WebGPU");
    const adapter = await navigator.gpu.requestAdapter();
    if (!adapter) throw new WebGPUError("WebGPU: no adapter");
    // float targets and tables are read through filtering samplers, as WebGL2 reads them
    const features = ["float32-filterable"];
    if (adapter.features.has(UNORM16)) features.push(UNORM16);
    for (const f of features.slice(0, 1)) {
      if (!adapter.features.has(f)) throw new WebGPUError(`WebGPU: this adapter lacks ${f}, which the page needs`);
    }
    const standard = Object.values(manifest.webgpu.programs).some((p) => [p.vertex, p.fragment].some(
      (s) => s.resources.some((r) => r.standard_layout)));
    if (standard && !(navigator.gpu.wgslLanguageFeatures || new Set()).has("uniform_buffer_standard_layout")) {
      throw new WebGPUError("WebGPU: this browser's WGSL lacks uniform_buffer_standard_layout, which the page's " +
                            "uniform arrays need (export with --api auto to fall back to WebGL2)");
    }
    const requiredLimits = Object.fromEntries(LIMITS.map((k) => [k, adapter.limits[k]]));
    const device = await adapter.requestDevice({requiredFeatures: features, requiredLimits});
    const presents = canPresent();
    const info = adapter.info || {};
    const gpu = new WebGPUBackend(canvas, device, manifest, `${info.vendor || "?"} / ${info.architecture || info.description || "?"}`,
                                  presents);
    await gpu._compile(sources, progress);
    return gpu;
  }

  // ``presents``: the frame goes to the canvas through a WebGPU context, else it is read back and put
  // into a 2D one (where the browser cannot present: headless Chromium loses its WebGPU instance)
  constructor(canvas, device, manifest, adapter, presents = true) {
    this.device = device;
    this.adapter = adapter;
    this.api = "webgpu";
    this.yDown = true;
    this.interfaces = manifest.webgpu.programs;
    this.errors = [];
    device.addEventListener("uncapturederror", (e) => this.errors.push(e.error.message));
    device.lost.then((e) => {   // draws and reads would return nothing: the page says so instead
      this.lost = `the WebGPU device was lost (${e.reason}): ${e.message}`;
      const page = window.inshade;
      if (page && !page.error) page.error = this.lost;
    });
    this.presentation = presents ? "webgpu" : "2d";
    this.context = canvas.getContext(this.presentation);
    if (!this.context) throw new WebGPUError(`this canvas gives no ${this.presentation} context`);
    if (presents) {
      this.context.configure({device, format: FRAME, alphaMode: "opaque",
                              usage: GPUTextureUsage.RENDER_ATTACHMENT | GPUTextureUsage.COPY_DST});
    }
    this.canvas = canvas;
    this.dummies = {};
    this.nearest = device.createSampler();
  }

  // every program's two modules, their compile messages awaited (errors name the file and line)
  async _compile(sources, progress) {
    const t0 = performance.now(), names = Object.keys(sources);
    this.programs = {};
    let done = 0;
    const seconds = () => ((performance.now() - t0) / 1000).toFixed(0);
    progress(`compiling ${names.length} WGSL programs`);
    await Promise.all(names.map(async (name) => {
      const modules = {};
      for (const [stage, ext] of [["vertex", "vert"], ["fragment", "frag"]]) {
        modules[stage] = this.device.createShaderModule({label: `${name}.${ext}`, code: sources[name][stage]});
        const info = await modules[stage].getCompilationInfo();
        const bad = info.messages.find((m) => m.type === "error");
        if (bad) throw new WebGPUError(`programs/${name}.${ext}.wgsl: line ${bad.lineNum}: ${bad.message}`);
      }
      this.programs[name] = this._program(name, modules);
      progress(`compiling shaders: ${++done} of ${names.length} programs ready (${seconds()} s)`);
    }));
    progress(`compiled ${names.length} WGSL programs in ${seconds()} s`);
  }

  _program(name, modules) {
    const iface = this.interfaces[name];
    const stages = [iface.fragment, iface.vertex];   // group 0, group 1
    const layouts = stages.map((s, g) => this.device.createBindGroupLayout({entries: s.resources.map((r) => {
      const entry = {binding: r.binding, visibility: g === 0 ? GPUShaderStage.FRAGMENT : GPUShaderStage.VERTEX};
      if (r.kind === "texture") entry.texture = {sampleType: r.sample_type, viewDimension: r.view};
      else if (r.kind === "sampler") entry.sampler = {type: "filtering"};
      else entry.buffer = {type: "uniform"};
      return entry;
    })}));
    const buffers = stages.map((s) => Object.fromEntries(s.resources.filter((r) => r.kind === "uniforms").map(
      (r) => [r.binding, this.device.createBuffer({size: r.size, usage: GPUBufferUsage.UNIFORM | GPUBufferUsage.COPY_DST})])));
    return {name, modules, iface, stages, layouts, buffers, pipelines: {},
            layout: this.device.createPipelineLayout({bindGroupLayouts: layouts})};
  }

  texture(rec, data) {
    const dev = this.device, mip = rec.generate_mipmaps;
    const {texture: tex, format, layers} = uploadTexture(dev, rec, data, mip ? {
      levels: mipCount(rec.size[0], rec.size[1]), usage: GPUTextureUsage.RENDER_ATTACHMENT} : {});
    if (mip) this._mipmaps(tex, format, layers);
    const linear = rec.filter === "linear", wrap = rec.wrap === "repeat" ? "repeat" : "clamp-to-edge";
    const sampler = dev.createSampler({addressModeU: wrap, addressModeV: wrap, addressModeW: "clamp-to-edge",
      magFilter: linear ? "linear" : "nearest", minFilter: linear ? "linear" : "nearest",
      mipmapFilter: mip ? "linear" : "nearest", maxAnisotropy: mip && linear ? Math.max(1, Math.floor(rec.anisotropy)) : 1});
    return {uniform: rec.uniform, view: tex.createView({dimension: VIEWS[rec.kind]}), sampler};
  }

  // an 8-bit sRGB image: sampling decodes to linear before filtering, as SRGB8_ALPHA8 does
  imageTexture(rec, bitmap) {
    const tex = this.device.createTexture({size: [bitmap.width, bitmap.height], format: "rgba8unorm-srgb",
                                           usage: USAGE() | GPUTextureUsage.RENDER_ATTACHMENT});
    this.device.queue.copyExternalImageToTexture({source: bitmap}, {texture: tex}, [bitmap.width, bitmap.height]);
    const filter = rec.filter === "linear" ? "linear" : "nearest";
    return {uniform: rec.uniform, view: tex.createView(),
            sampler: this.device.createSampler({magFilter: filter, minFilter: filter})};
  }

  blocks(blocks, data) {
    return blocks.map((b) => {
      const bytes = new Uint8Array(data, b.data[0], b.data[1]);
      const buffer = this.device.createBuffer({size: Math.ceil(Math.max(bytes.length, 16) / 16) * 16,
                                               usage: GPUBufferUsage.UNIFORM | GPUBufferUsage.COPY_DST});
      this.device.queue.writeBuffer(buffer, 0, bytes);
      return {name: b.name, buffer};
    });
  }

  target(width, height, formats, depth = false) {
    const usage = GPUTextureUsage.RENDER_ATTACHMENT | GPUTextureUsage.TEXTURE_BINDING | GPUTextureUsage.COPY_SRC;
    const textures = formats.map((f) => {
      const format = TARGET_FORMATS[f];
      const tex = this.device.createTexture({size: [width, height], format, usage});
      return {view: tex.createView(), sampler: this.nearest, format};
    });
    const depthView = depth ? this.device.createTexture({size: [width, height], format: DEPTH,
                                                         usage: GPUTextureUsage.RENDER_ATTACHMENT}).createView() : null;
    return {textures, formats: textures.map((t) => t.format), depthView, width, height, depth};
  }

  geometry(program, mesh, data) {
    const attributes = this.interfaces[program].vertex.attributes;
    const buffers = Object.entries(attributes).map(([name, location]) => {
      const a = mesh.attributes[name];
      if (!a) throw new WebGPUError(`programs/${program}.vert.wgsl: the mesh has no attribute ${name}`);
      return {buffer: this._buffer(new Float32Array(data, a.data[0], a.data[1] / 4), GPUBufferUsage.VERTEX),
              layout: {arrayStride: a.size * 4, attributes: [{shaderLocation: location, offset: 0,
                                                              format: a.size === 1 ? "float32" : `float32x${a.size}`}]}};
    });
    const index = mesh.indices ? this._buffer(new Uint32Array(data, mesh.indices[0], mesh.indices[1] / 4), GPUBufferUsage.INDEX)
      : null;
    return {buffers, index, count: mesh.count};
  }

  _buffer(array, usage) {
    const buffer = this.device.createBuffer({size: Math.ceil(array.byteLength / 4) * 4, usage: usage | GPUBufferUsage.COPY_DST});
    this.device.queue.writeBuffer(buffer, 0, array);
    return buffer;
  }

  clear(target, colour = [0, 0, 0, 0]) {
    const encoder = this.device.createCommandEncoder();
    const value = {r: colour[0], g: colour[1], b: colour[2], a: colour[3]};
    encoder.beginRenderPass({
      colorAttachments: target.textures.map((t) => ({view: t.view, loadOp: "clear", storeOp: "store",
                                                      clearValue: t.format === "r32uint" ? {r: 0, g: 0, b: 0, a: 0} : value})),
      depthStencilAttachment: target.depthView ? {view: target.depthView, depthClearValue: 1, depthLoadOp: "clear",
                                                  depthStoreOp: "store"} : undefined}).end();
    this.device.queue.submit([encoder.finish()]);
  }

  draw(program, target, {textures = [], blocks = [], uniforms = {}, size, geometry = null}) {
    const prog = this.programs[program], dev = this.device;
    if (!target && !this.frameTexture) this._frame();
    const views = target ? target.textures.map((t) => t.view) : [this.frameTexture.createView()];
    const formats = target ? target.formats : [FRAME];
    const pipeline = this._pipeline(prog, formats, geometry);
    const groups = prog.stages.map((stage, g) => dev.createBindGroup({layout: prog.layouts[g], entries:
      stage.resources.map((r) => ({binding: r.binding, resource: this._resource(prog, g, r, textures, blocks, uniforms)}))}));
    const encoder = dev.createCommandEncoder();
    const pass = encoder.beginRenderPass({
      colorAttachments: views.map((view) => ({view, loadOp: "load", storeOp: "store"})),
      depthStencilAttachment: geometry ? {view: target.depthView, depthLoadOp: "load", depthStoreOp: "store"} : undefined});
    pass.setViewport(0, 0, size[0], size[1], 0, 1);
    pass.setPipeline(pipeline);
    groups.forEach((group, g) => pass.setBindGroup(g, group));
    if (geometry) {
      geometry.buffers.forEach((b, slot) => pass.setVertexBuffer(slot, b.buffer));
      if (geometry.index) {
        pass.setIndexBuffer(geometry.index, "uint32");
        pass.drawIndexed(geometry.count);
      } else {
        pass.draw(geometry.count);
      }
    } else {
      pass.draw(3);
    }
    pass.end();
    if (!target && this.presentation === "webgpu") {   // the frame onto the canvas
      encoder.copyTextureToTexture({texture: this.frameTexture}, {texture: this.context.getCurrentTexture()},
                                   [this.canvas.width, this.canvas.height]);
    }
    dev.queue.submit([encoder.finish()]);
  }

  _frame() {
    this.frameTexture = this.device.createTexture({size: [this.canvas.width, this.canvas.height], format: FRAME,
      usage: GPUTextureUsage.RENDER_ATTACHMENT | GPUTextureUsage.COPY_SRC});
  }

  _pipeline(prog, formats, geometry) {
    const key = pipelineKey(formats, geometry);
    prog.pipelines[key] ||= this.device.createRenderPipeline(this._describe(prog, formats, geometry));
    return prog.pipelines[key];
  }

  // the pipelines of ``passes`` ([{program, target, geometry}]) made before the first frame, counted as
  // they are ready (their compile is the long part: a software driver compiles the shader there)
  async prepare(passes, progress = () => {}) {
    const t0 = performance.now(), seconds = () => ((performance.now() - t0) / 1000).toFixed(0);
    let done = 0;
    progress(`compiling ${passes.length} pipelines`);
    await Promise.all(passes.map(async ({program, target, geometry}) => {
      const prog = this.programs[program], formats = target ? target.formats : [FRAME];
      const key = pipelineKey(formats, geometry);
      if (!prog.pipelines[key]) {
        const pipeline = await this.device.createRenderPipelineAsync(this._describe(prog, formats, geometry));
        prog.pipelines[key] ||= pipeline;
      }
      progress(`compiling pipelines: ${++done} of ${passes.length} ready (${seconds()} s)`);
    }));
    progress(`compiled ${passes.length} pipelines in ${seconds()} s; drawing the first frame`);
    await nextFrame();
  }

  _describe(prog, formats, geometry) {
    const written = new Set(Object.values(prog.iface.fragment.outputs));
    return {
      label: prog.name, layout: prog.layout,
      vertex: {module: prog.modules.vertex, entryPoint: "main", buffers: geometry ? geometry.buffers.map((b) => b.layout) : []},
      fragment: {module: prog.modules.fragment, entryPoint: "main",
                 targets: formats.map((format, k) => ({format, writeMask: written.has(k) ? GPUColorWrite.ALL : 0}))},
      primitive: {topology: "triangle-list", cullMode: "none"},
      depthStencil: geometry ? {format: DEPTH, depthWriteEnabled: true, depthCompare: "less"} : undefined};
  }

  // what binding ``r`` of group ``g`` takes: the last texture of that uniform name (else a blank
  // one), its sampler, a named block, or the stage's uniforms packed as the manifest lays them out
  _resource(prog, g, r, textures, blocks, uniforms) {
    if (r.kind === "uniforms") {
      const buffer = prog.buffers[g][r.binding];
      this.device.queue.writeBuffer(buffer, 0, pack(prog.stages[g].uniforms, uniforms, r.size));
      return {buffer};
    }
    if (r.kind === "block") {
      const block = blocks.find((b) => b.name === r.name);
      if (!block) throw new WebGPUError(`programs/${prog.name}: no data for uniform block ${r.name}`);
      return {buffer: block.buffer};
    }
    const uniform = r.name.replace(/_(image|sampler)$/, "");
    const t = textures.findLast((x) => x.uniform === uniform);
    if (r.kind === "sampler") return t ? t.sampler : this.nearest;
    return t ? t.view : this._dummy(r);
  }

  _dummy(r) {   // a 1 x 1 texture of zeros for a texture the pass does not give (GL reads unit 0's)
    const key = `${r.view}/${r.sample_type}`;
    if (!this.dummies[key]) {
      const format = {float: "rgba8unorm", uint: "r32uint", sint: "r32sint"}[r.sample_type];
      this.dummies[key] = this.device.createTexture({size: [1, 1, 1], format, usage: USAGE(),
        dimension: r.view === "3d" ? "3d" : "2d"}).createView({dimension: r.view});
    }
    return this.dummies[key];
  }

  // an image's mip chain from its level 0: each level the bilinear mean of the one above (a 2 x 2 box)
  _mipmaps(texture, format, layers) {
    const dev = this.device;
    if (!this.mipProgram) {
      const module = dev.createShaderModule({code: MIP_WGSL});
      this.mipProgram = {module, pipelines: {},
                         sampler: dev.createSampler({minFilter: "linear", magFilter: "linear"})};
    }
    const mp = this.mipProgram;
    mp.pipelines[format] ||= dev.createRenderPipeline({layout: "auto", vertex: {module: mp.module, entryPoint: "vs"},
      fragment: {module: mp.module, entryPoint: "fs", targets: [{format}]}, primitive: {topology: "triangle-list"}});
    const pipeline = mp.pipelines[format];
    const encoder = dev.createCommandEncoder();
    for (let layer = 0; layer < layers; ++layer) {
      for (let k = 1; k < texture.mipLevelCount; ++k) {
        const view = (level) => texture.createView({dimension: "2d", baseMipLevel: level, mipLevelCount: 1,
                                                     baseArrayLayer: layer, arrayLayerCount: 1});
        const group = dev.createBindGroup({layout: pipeline.getBindGroupLayout(0),
                                           entries: [{binding: 0, resource: mp.sampler}, {binding: 1, resource: view(k - 1)}]});
        const pass = encoder.beginRenderPass({colorAttachments: [{view: view(k), loadOp: "clear", storeOp: "store"}]});
        pass.setPipeline(pipeline);
        pass.setBindGroup(0, group);
        pass.draw(3);
        pass.end();
      }
    }
    dev.queue.submit([encoder.finish()]);
  }

  async finish() {
    if (this.presentation === "2d") {
      const [w, h] = [this.canvas.width, this.canvas.height];
      this.context.putImageData(new ImageData(new Uint8ClampedArray((await this._read(w, h)).buffer), w, h), 0, 0);
    }
    await this.device.queue.onSubmittedWorkDone();
    if (this.lost) throw new WebGPUError(this.lost);
    if (this.errors.length) throw new WebGPUError(`WebGPU: ${this.errors[0]}`);
  }

  async settled() {
    await nextFrame();
    if (this.lost) throw new WebGPUError(this.lost);
  }

  // the canvas's lower-left w x h as 8-bit RGBA, rows top to bottom (the frame's rows already run so)
  pixels(w, h) { return this._read(w, h); }

  async _read(w, h) {
    const row = Math.ceil(w * 4 / 256) * 256, dev = this.device;
    const buffer = dev.createBuffer({size: row * h, usage: GPUBufferUsage.COPY_DST | GPUBufferUsage.MAP_READ});
    const encoder = dev.createCommandEncoder();
    encoder.copyTextureToBuffer({texture: this.frameTexture, origin: [0, this.canvas.height - h]},
                                {buffer, bytesPerRow: row}, [w, h]);
    dev.queue.submit([encoder.finish()]);
    await buffer.mapAsync(GPUMapMode.READ);
    const raw = new Uint8Array(buffer.getMappedRange()), out = new Uint8Array(w * h * 4);
    for (let y = 0; y < h; ++y) out.set(raw.subarray(y * row, y * row + w * 4), y * w * 4);
    buffer.unmap();
    return out;
  }
}

// whether the frame can go to the canvas through a WebGPU context: headless Chromium loses its WebGPU
// instance once a canvas hands out a texture (every later call fails), so there it is read back into
// a 2D canvas instead; ``?present=webgpu|2d`` overrides
function canPresent() {
  const asked = new URLSearchParams(location.search).get("present");
  return asked ? asked === "webgpu" : !navigator.userAgent.includes("HeadlessChrome");
}

const pipelineKey = (formats, geometry) => formats.join() + (geometry ? "+depth" : "");

function mipCount(w, h) {
  return Math.floor(Math.log2(Math.max(w, h))) + 1;
}

// the stage's uniforms as bytes: each member at its offset, arrays and matrix columns at their strides
function pack(layouts, values, size) {
  const bytes = new ArrayBuffer(size), view = new DataView(bytes);
  for (const [name, lay] of Object.entries(layouts)) {
    if (!(name in values)) continue;
    const raw = values[name], flat = Array.isArray(raw) || ArrayBuffer.isView(raw) ? raw : [raw];
    const n = lay.rows * lay.cols;
    for (let i = 0; i < lay.count && i * n < flat.length; ++i) {
      for (let c = 0; c < lay.cols; ++c) {
        for (let r = 0; r < lay.rows; ++r) {
          const v = Number(flat[i * n + c * lay.rows + r] ?? 0), at = lay.offset + i * lay.stride + c * lay.matrix_stride + r * 4;
          if (lay.kind === "f") view.setFloat32(at, v, true);
          else if (lay.kind === "i") view.setInt32(at, Math.round(v), true);
          else view.setUint32(at, Math.round(v), true);
        }
      }
    }
  }
  return bytes;
}

const MIP_WGSL = `
@group(0) @binding(0) var s: sampler;
@group(0) @binding(1) var t: texture_2d<f32>;
struct V { @builtin(position) p: vec4f, @location(0) uv: vec2f };
@vertex fn vs(@builtin(vertex_index) i: u32) -> V {
  let c = vec2f(f32((i & 1u) << 2u), f32((i & 2u) << 1u));
  return V(vec4f(c - 1.0, 0.0, 1.0), vec2f(c.x, 2.0 - c.y) * 0.5);
}
@fragment fn fs(v: V) -> @location(0) vec4f { return textureSample(t, s, v.uv); }
`;
