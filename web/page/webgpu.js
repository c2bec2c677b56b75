// The exported network on WebGPU: its WGSL (the same code inshade's compute driver checks against
// torch) run as a compute pass over the evaluation batch, each resource at its binding of group 0
// (manifest.evaluate_webgpu, written by web/export.py).

import { base64 } from "./inshade.js";

// texel formats by inshade dtype and channel count (runtime/compute/textures.py), with the value of
// an alpha channel RGB data gains (WebGPU has no three-channel formats)
const FORMATS = {
  f4: {formats: {1: "r32float", 2: "rg32float", 4: "rgba32float"}, array: Float32Array, alpha: 1.0},
  f2: {formats: {1: "r16float", 2: "rg16float", 4: "rgba16float"}, array: Uint16Array, alpha: 0x3c00},
  f1: {formats: {1: "r8unorm", 2: "rg8unorm", 4: "rgba8unorm"}, array: Uint8Array, alpha: 255},
  nu2: {formats: {1: "r16unorm", 2: "rg16unorm", 4: "rgba16unorm"}, array: Uint16Array, alpha: 65535},
  u4: {formats: {1: "r32uint", 2: "rg32uint", 4: "rgba32uint"}, array: Uint32Array, alpha: 1},
  u1: {formats: {1: "r8uint", 2: "rg8uint", 4: "rgba8uint"}, array: Uint8Array, alpha: 1},
};
export const UNORM16 = "texture-formats-tier1";   // 16-bit normalised formats in WebGPU

export class WebGPUError extends Error {}

async function device(resources) {
  if (!navigator.gpu) throw new WebGPUError("this browser has no WebGPU");
  const adapter = await navigator.gpu.requestAdapter();
  if (!adapter) throw new WebGPUError("WebGPU: no adapter");
  const want = [];
  if (resources.some((r) => r.sampler != null && r.dtype === "f4")) want.push("float32-filterable");
  if (resources.some((r) => r.dtype === "nu2") && adapter.features.has(UNORM16)) want.push(UNORM16);
  for (const f of want) {
    if (!adapter.features.has(f)) throw new WebGPUError(`WebGPU: this adapter lacks ${f}, which this network needs`);
  }
  const info = adapter.info || {};
  return {device: await adapter.requestDevice({requiredFeatures: want}),
          adapter: `${info.vendor || "?"} / ${info.architecture || info.description || "?"}`};
}

// one level's texels as the format holds them: RGB gains an alpha; 16-bit normalised cells become
// floats q / 65535 where the device has no such format
function texels(rec, data, [offset, nbytes], unorm16) {
  const spec = FORMATS[rec.dtype];
  let values = new spec.array(data, offset, nbytes / spec.array.BYTES_PER_ELEMENT);
  if (rec.channels === 3) {
    const n = values.length / 3, out = new spec.array(n * 4);
    for (let i = 0; i < n; ++i) {
      out.set(values.subarray(i * 3, i * 3 + 3), i * 4);
      out[i * 4 + 3] = spec.alpha;
    }
    values = out;
  }
  if (rec.dtype === "nu2" && !unorm16) values = Float32Array.from(values, (q) => q / 65535);
  return values;
}

// a texture record's texels in a new texture: its levels (``levels`` in all: more where a mip chain is
// made later) with ``usage`` besides sampling and uploads; {texture, format, layers}
export function uploadTexture(dev, rec, data, {levels = rec.levels.length, usage = 0} = {}) {
  const unorm16 = dev.features.has(UNORM16);
  const dtype = rec.dtype === "nu2" && !unorm16 ? "f4" : rec.dtype;
  const channels = rec.channels === 3 ? 4 : rec.channels;
  const format = FORMATS[dtype].formats[channels];
  const depth = rec.kind === "2d" ? 1 : rec.size[2];
  const tex = dev.createTexture({size: [rec.size[0], rec.size[1], depth], format, mipLevelCount: levels,
                                 dimension: rec.kind === "3d" ? "3d" : "2d",
                                 usage: GPUTextureUsage.TEXTURE_BINDING | GPUTextureUsage.COPY_DST | usage});
  rec.levels.forEach((level, k) => {
    const values = texels(rec, data, level, unorm16);
    const w = Math.max(rec.size[0] >> k, 1), h = Math.max(rec.size[1] >> k, 1);
    const d = rec.kind === "3d" ? Math.max(depth >> k, 1) : depth;
    dev.queue.writeTexture({texture: tex, mipLevel: k}, values,
                           {bytesPerRow: w * channels * values.BYTES_PER_ELEMENT, rowsPerImage: h}, [w, h, d]);
  });
  return {texture: tex, format, layers: depth};
}

function texture(dev, rec, data) {
  return uploadTexture(dev, rec, data).texture.createView({dimension: rec.view});
}

function bindings(dev, e, data) {
  const layout = [], group = [];
  for (const r of e.resources) {
    if (r.buffer) {
      const bytes = new Uint8Array(data, r.data[0], r.data[1]);
      const buf = dev.createBuffer({size: Math.max(16, bytes.length),
                                    usage: (r.buffer === "uniform" ? GPUBufferUsage.UNIFORM : GPUBufferUsage.STORAGE)
                                      | GPUBufferUsage.COPY_DST});
      dev.queue.writeBuffer(buf, 0, bytes);
      layout.push({binding: r.binding, visibility: GPUShaderStage.COMPUTE, buffer: {type: r.buffer}});
      group.push({binding: r.binding, resource: {buffer: buf}});
      continue;
    }
    layout.push({binding: r.binding, visibility: GPUShaderStage.COMPUTE,
                 texture: {sampleType: r.sample_type, viewDimension: r.view}});
    group.push({binding: r.binding, resource: texture(dev, r, data)});
    if (r.sampler != null) {   // bilinear within a level, the nearest level, the texture's wrap
      const mode = r.wrap === "repeat" ? "repeat" : "clamp-to-edge";
      layout.push({binding: r.sampler, visibility: GPUShaderStage.COMPUTE, sampler: {type: "filtering"}});
      group.push({binding: r.sampler, resource: dev.createSampler({addressModeU: mode, addressModeV: mode,
        addressModeW: mode, magFilter: "linear", minFilter: "linear", mipmapFilter: "nearest"})});
    }
  }
  return [layout, group];
}

const WORKGROUP = 64, MAX_GROUPS = 65535;

// ``repeats``: the batch dispatched and read back that many times (inshade bench web), ``times`` the ms of each.
export async function evaluateWebGPU({manifest, data}, {repeats = 1} = {}) {
  const e = manifest.evaluate_webgpu;
  if (!e) throw new WebGPUError("this asset has no network to evaluate");
  if (e.unavailable) throw new WebGPUError(`WGSL: ${e.unavailable}`);
  const {device: dev, adapter} = await device(e.resources);
  const errors = [];
  dev.addEventListener("uncapturederror", (ev) => errors.push(ev.error.message));
  const n = e.count;
  const inputs = new Float32Array(data, e.inputs[0], e.inputs[1] / 4);
  const uint = new Set(e.uint_lanes);
  const floats = new Float32Array(n * e.in_blocks * 4), ids = new Uint32Array(n * Math.max(e.in_uint_blocks, 1) * 4);
  for (let i = 0; i < n; ++i) {
    let f = 0, u = 0;
    for (let j = 0; j < e.in_dim; ++j) {
      const x = inputs[i * e.in_dim + j];
      if (uint.has(j)) ids[i * e.in_uint_blocks * 4 + u++] = x;
      else floats[i * e.in_blocks * 4 + f++] = x;
    }
  }
  const storage = (array, usage = 0) => {
    const buf = dev.createBuffer({size: Math.max(16, array.byteLength), usage: GPUBufferUsage.STORAGE | GPUBufferUsage.COPY_DST | usage});
    dev.queue.writeBuffer(buf, 0, array);
    return buf;
  };
  const outBytes = n * e.out_blocks * 16;
  const batch = [storage(floats), dev.createBuffer({size: outBytes, usage: GPUBufferUsage.STORAGE | GPUBufferUsage.COPY_SRC})];
  if (e.uint_lanes.length) batch.push(storage(ids));
  const kinds = ["read-only-storage", "storage", "read-only-storage"];
  const [resLayout, resGroup] = bindings(dev, e, data);
  const layouts = [dev.createBindGroupLayout({entries: resLayout}),
                   dev.createBindGroupLayout({entries: batch.map((_, b) => ({binding: b, visibility: GPUShaderStage.COMPUTE,
                                                                              buffer: {type: kinds[b]}}))})];
  const groups = [dev.createBindGroup({layout: layouts[0], entries: resGroup}),
                  dev.createBindGroup({layout: layouts[1], entries: batch.map((buf, b) => ({binding: b, resource: {buffer: buf}}))})];
  const module = dev.createShaderModule({code: e.wgsl});
  const info = await module.getCompilationInfo();
  const problems = info.messages.filter((m) => m.type === "error");
  if (problems.length) throw new WebGPUError(`WGSL: line ${problems[0].lineNum}: ${problems[0].message}`);
  const pipeline = await dev.createComputePipelineAsync({layout: dev.createPipelineLayout({bindGroupLayouts: layouts}),
                                                         compute: {module, entryPoint: "main"}});
  const read = dev.createBuffer({size: outBytes, usage: GPUBufferUsage.MAP_READ | GPUBufferUsage.COPY_DST});
  const times = [];
  let blocks;
  for (let r = 0; r < repeats; ++r) {
    const start = performance.now();
    const encoder = dev.createCommandEncoder();
    const pass = encoder.beginComputePass();
    pass.setPipeline(pipeline);
    groups.forEach((g, i) => pass.setBindGroup(i, g));
    const total = Math.ceil(n / WORKGROUP);
    pass.dispatchWorkgroups(Math.min(total, MAX_GROUPS), Math.ceil(total / MAX_GROUPS));
    pass.end();
    encoder.copyBufferToBuffer(batch[1], 0, read, 0, outBytes);
    dev.queue.submit([encoder.finish()]);
    await read.mapAsync(GPUMapMode.READ);
    blocks = new Float32Array(read.getMappedRange().slice(0));
    read.unmap();
    times.push(performance.now() - start);
  }
  const ms = times[0];
  if (errors.length) throw new WebGPUError(`WebGPU: ${errors[0]}`);
  const outputs = new Float32Array(n * e.out_dim);
  for (let i = 0; i < n; ++i) for (let j = 0; j < e.out_dim; ++j) outputs[i * e.out_dim + j] = blocks[i * e.out_blocks * 4 + j];
  return {outputs, count: n, outDim: e.out_dim, ms, times, adapter, base64: base64(new Uint8Array(outputs.buffer))};
}
