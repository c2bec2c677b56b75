// inshade.js: the page side of `inshade export-web`. It replays what inshade's GL runtime
// (runtime/renderer.py SceneRenderer) draws, from the exported folder: manifest.json (what to draw),
// data.bin (texels, uniform blocks, vertices) and programs/*.glsl (GLSL ES 3.00 from the resolver).
// Its concepts are the runtime's: programs, passes (a mesh G-buffer pass, the scene pass, the
// running mean of a stochastic pass, the display pass, the present pass), float render targets,
// resources bound by sampler and block name, uniforms from the camera, the settings and the
// manifest. It names no technique. No framework, no build step.

const gl2 = WebGL2RenderingContext;

// texture dtypes (codegen.glsl.TextureResource) -> internal formats by channel count, format, type
const DTYPES = {
  f4: {internal: [gl2.R32F, gl2.RG32F, gl2.RGB32F, gl2.RGBA32F], type: gl2.FLOAT, array: Float32Array},
  f2: {internal: [gl2.R16F, gl2.RG16F, gl2.RGB16F, gl2.RGBA16F], type: gl2.HALF_FLOAT, array: Uint16Array},
  f1: {internal: [gl2.R8, gl2.RG8, gl2.RGB8, gl2.RGBA8], type: gl2.UNSIGNED_BYTE, array: Uint8Array},
  u4: {internal: [gl2.R32UI, gl2.RG32UI, gl2.RGB32UI, gl2.RGBA32UI], type: gl2.UNSIGNED_INT, array: Uint32Array,
       integer: true},
  u1: {internal: [gl2.R8UI, gl2.RG8UI, gl2.RGB8UI, gl2.RGBA8UI], type: gl2.UNSIGNED_BYTE, array: Uint8Array,
       integer: true},
  nu2: {internal: [0x822A, 0x822C, 0x8054, 0x805B], type: gl2.UNSIGNED_SHORT, array: Uint16Array},  // EXT_texture_norm16
};
const FORMATS = [gl2.RED, gl2.RG, gl2.RGB, gl2.RGBA];
const INTEGER_FORMATS = [gl2.RED_INTEGER, gl2.RG_INTEGER, gl2.RGB_INTEGER, gl2.RGBA_INTEGER];
// render-target formats (runtime/render.py TARGET_FORMATS)
const TARGETS = {
  rgba32f: [gl2.RGBA32F, gl2.RGBA, gl2.FLOAT], rg32f: [gl2.RG32F, gl2.RG, gl2.FLOAT],
  r32f: [gl2.R32F, gl2.RED, gl2.FLOAT], r32ui: [gl2.R32UI, gl2.RED_INTEGER, gl2.UNSIGNED_INT],
};
const SAMPLE_CAP = 256;   // a stochastic program stops adding samples here
const PREVIEW = 4;        // the first frame is drawn at 1 / PREVIEW of the size, then the full one

export class WebGLError extends Error {}

async function fetchChecked(url, how) {
  const response = await fetch(url);
  if (!response.ok) throw new WebGLError(`${url}: ${response.status} ${response.statusText}`);
  return how === "json" ? response.json() : how === "text" ? response.text() : response.arrayBuffer();
}

// The API a page draws with: ``api`` if given, else the first of the export's that this browser has
// (WebGPU needs an adapter, not only navigator.gpu).
async function chooseApi(manifest, api) {
  const apis = manifest.apis || ["webgl2"];
  if (api !== "auto") {
    if (!apis.includes(api)) throw new WebGLError(`this page was exported without ${api} programs (export-web --api ${api} or auto)`);
    return api;
  }
  for (const a of apis) {
    if (a === "webgl2" || (navigator.gpu && await navigator.gpu.requestAdapter())) return a;
  }
  throw new WebGLError("this browser has no WebGPU, and the page was exported for WebGPU only (export-web --api auto)");
}

// Everything an exported folder holds: the manifest, the bytes and every program's sources for
// ``api`` ("auto": chosen by chooseApi).
export async function loadExport(base = "./", api = "webgl2") {
  const manifest = await fetchChecked(base + "manifest.json", "json");
  if (manifest.format !== "inshade-web 1") throw new WebGLError(`manifest.json: format: unknown ${manifest.format}`);
  api = await chooseApi(manifest, api);
  const data = await fetchChecked(base + "data.bin", "bytes");
  const names = new Set(Object.values(manifest.programs));
  if (manifest.mesh) names.add(manifest.mesh.program);
  if (api === "webgl2") for (const name of (manifest.evaluate && manifest.evaluate.passes) || []) names.add(name);
  const reference = manifest.display.reference;
  const images = {};
  if (reference && reference.image) {   // decoded as stored: no colour conversion, no premultiplication
    const blob = new Blob([await fetchChecked(base + reference.image, "bytes")]);
    images[reference.image] = await createImageBitmap(blob, {colorSpaceConversion: "none", premultiplyAlpha: "none",
                                                             imageOrientation: "flipY"});   // uv (0, 0) = bottom-left
  }
  const sources = {}, ext = api === "webgpu" ? "wgsl" : "glsl";
  await Promise.all([...names].map(async (name) => {
    const [vertex, fragment] = await Promise.all([
      fetchChecked(`${base}programs/${name}.vert.${ext}`, "text"), fetchChecked(`${base}programs/${name}.frag.${ext}`, "text")]);
    sources[name] = {vertex, fragment};
  }));
  return {manifest, data, sources, images, api};
}

const CONTEXT_LOST = "the WebGL context was lost (the browser reset its GPU process or gave up on a draw)";

// Resolves a frame later, once the browser has had the chance to report a lost context (it does so
// asynchronously: draws and reads before that return blanks); rejects if it has.
export async function settled(gl) {
  await new Promise((resolve) => requestAnimationFrame(resolve));
  if (gl.isContextLost()) throw new WebGLError(CONTEXT_LOST);
}

export function createContext(canvas, manifest) {
  const gl = canvas.getContext("webgl2", {antialias: false, preserveDrawingBuffer: true, alpha: false,
                                          depth: false, premultipliedAlpha: false});
  if (!gl) throw new WebGLError("this browser has no WebGL2");
  // A lost context draws and reads nothing, without a GL error: the page says so instead of showing
  // (or handing back) blanks
  canvas.addEventListener("webglcontextlost", () => {
    const page = window.inshade;
    if (page && !page.error) page.error = CONTEXT_LOST;
  });
  for (const name of manifest.requires.extensions) {
    if (!gl.getExtension(name)) throw new WebGLError(`WebGL2: this browser lacks ${name}, which this asset needs`);
  }
  for (const [name, need] of Object.entries(manifest.requires.limits)) {
    const have = gl.getParameter(gl[name.replace(/^GL_/, "")]);
    if (have < need) throw new WebGLError(`WebGL2: this asset needs ${name} >= ${need}; this browser has ${have}`);
  }
  return gl;
}

// --- GL objects --------------------------------------------------------------------------------

// Compiling is started for every program first and its status read only at the end: with
// KHR_parallel_shader_compile the browser compiles meanwhile and the page can say how far it is
// (a big network's program takes seconds to minutes on a software rasteriser).
function startCompile(gl, name, sources) {
  const program = gl.createProgram();
  const shaders = [];
  for (const [stage, type] of [["vertex", gl.VERTEX_SHADER], ["fragment", gl.FRAGMENT_SHADER]]) {
    const shader = gl.createShader(type);
    gl.shaderSource(shader, sources[stage]);
    gl.compileShader(shader);
    gl.attachShader(program, shader);
    shaders.push([stage, shader]);
  }
  gl.linkProgram(program);
  return {name, program, shaders};
}

function finishCompile(gl, {name, program, shaders}) {
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) {
    for (const [stage, shader] of shaders) {
      if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) {
        throw new WebGLError(`programs/${name}.${stage === "vertex" ? "vert" : "frag"}.glsl: ${gl.getShaderInfoLog(shader)}`);
      }
    }
    throw new WebGLError(`programs/${name}: link: ${gl.getProgramInfoLog(program)}`);
  }
  const uniforms = {};
  const count = gl.getProgramParameter(program, gl.ACTIVE_UNIFORMS);
  for (let i = 0; i < count; ++i) {
    const info = gl.getActiveUniform(program, i);
    const base = info.name.replace(/\[0\]$/, "");
    uniforms[base] = {location: gl.getUniformLocation(program, info.name), type: info.type, size: info.size};
  }
  return {name, program, uniforms};
}

function compile(gl, name, sources) {
  return finishCompile(gl, startCompile(gl, name, sources));
}

const nextFrame = () => new Promise((resolve) => requestAnimationFrame(resolve));

// Every program of ``sources`` compiled, reporting progress (a line of text) as it goes.
export async function compileAll(gl, sources, progress = () => {}) {
  const t0 = performance.now();
  const pending = Object.entries(sources).map(([name, src]) => startCompile(gl, name, src));
  const parallel = gl.getExtension("KHR_parallel_shader_compile");
  const seconds = () => ((performance.now() - t0) / 1000).toFixed(0);
  if (parallel) {
    for (;;) {
      const done = pending.filter((p) => gl.getProgramParameter(p.program, parallel.COMPLETION_STATUS_KHR)).length;
      if (done === pending.length) break;
      progress(`compiling shaders: ${done} of ${pending.length} programs ready (${seconds()} s)`);
      await new Promise((resolve) => setTimeout(resolve, 100));
    }
  } else {   // the first status read waits for the whole compile: say so, and let the page paint it first
    progress(`compiling ${pending.length} shader programs (this browser reports no progress)`);
    await nextFrame();
  }
  const programs = Object.fromEntries(pending.map((p) => [p.name, finishCompile(gl, p)]));
  progress(`compiled ${pending.length} shader programs in ${seconds()} s; drawing the first frame`);
  await nextFrame();
  return programs;
}

function setUniform(gl, prog, name, value) {
  const u = prog.uniforms[name];
  if (!u) return;
  const v = Array.isArray(value) || ArrayBuffer.isView(value) ? value : [value];
  switch (u.type) {
    case gl.FLOAT: gl.uniform1fv(u.location, v); break;
    case gl.FLOAT_VEC2: gl.uniform2fv(u.location, v); break;
    case gl.FLOAT_VEC3: gl.uniform3fv(u.location, v); break;
    case gl.FLOAT_VEC4: gl.uniform4fv(u.location, v); break;
    case gl.FLOAT_MAT3: gl.uniformMatrix3fv(u.location, false, v); break;
    case gl.FLOAT_MAT4: gl.uniformMatrix4fv(u.location, false, v); break;
    case gl.INT_VEC2: gl.uniform2iv(u.location, v); break;
    case gl.INT_VEC3: gl.uniform3iv(u.location, v); break;
    case gl.INT_VEC4: gl.uniform4iv(u.location, v); break;
    case gl.UNSIGNED_INT: gl.uniform1uiv(u.location, v); break;
    case gl.UNSIGNED_INT_VEC2: gl.uniform2uiv(u.location, v); break;
    case gl.UNSIGNED_INT_VEC3: gl.uniform3uiv(u.location, v); break;
    case gl.UNSIGNED_INT_VEC4: gl.uniform4uiv(u.location, v); break;
    default: gl.uniform1iv(u.location, v.map((x) => Math.round(x)));   // int, bool, samplers
  }
}

function texture(gl, rec, data) {
  const dtype = DTYPES[rec.dtype];
  if (!dtype) throw new WebGLError(`texture ${rec.uniform}: unknown dtype ${rec.dtype}`);
  const target = {"2d": gl.TEXTURE_2D, "3d": gl.TEXTURE_3D, "2d_array": gl.TEXTURE_2D_ARRAY}[rec.kind];
  const tex = gl.createTexture();
  gl.bindTexture(target, tex);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  const internal = dtype.internal[rec.channels - 1];
  const format = (dtype.integer ? INTEGER_FORMATS : FORMATS)[rec.channels - 1];
  rec.levels.forEach(([offset, nbytes], k) => {
    const texels = new dtype.array(data, offset, nbytes / dtype.array.BYTES_PER_ELEMENT);
    const w = Math.max(rec.size[0] >> k, 1), h = Math.max(rec.size[1] >> k, 1);
    if (rec.kind === "2d") {
      gl.texImage2D(target, k, internal, w, h, 0, format, dtype.type, texels);
    } else {
      const d = rec.kind === "3d" ? Math.max(rec.size[2] >> k, 1) : rec.size[2];
      gl.texImage3D(target, k, internal, w, h, d, 0, format, dtype.type, texels);
    }
  });
  const linear = rec.filter === "linear";
  const wrap = rec.wrap === "repeat" ? gl.REPEAT : gl.CLAMP_TO_EDGE;
  gl.texParameteri(target, gl.TEXTURE_WRAP_S, wrap);
  gl.texParameteri(target, gl.TEXTURE_WRAP_T, wrap);
  gl.texParameteri(target, gl.TEXTURE_WRAP_R, gl.CLAMP_TO_EDGE);
  gl.texParameteri(target, gl.TEXTURE_MAG_FILTER, linear ? gl.LINEAR : gl.NEAREST);
  let min = linear ? gl.LINEAR : gl.NEAREST;
  if (rec.generate_mipmaps) {
    gl.generateMipmap(target);
    min = gl.LINEAR_MIPMAP_LINEAR;
    const aniso = gl.getExtension("EXT_texture_filter_anisotropic");
    if (aniso && rec.anisotropy > 1) {
      gl.texParameterf(target, aniso.TEXTURE_MAX_ANISOTROPY_EXT,
                       Math.min(rec.anisotropy, gl.getParameter(aniso.MAX_TEXTURE_MAX_ANISOTROPY_EXT)));
    }
  } else if (rec.levels.length > 1) {   // the nearest level, bilinear within it (as the runtime)
    min = linear ? gl.LINEAR_MIPMAP_NEAREST : gl.NEAREST_MIPMAP_NEAREST;
    gl.texParameteri(target, gl.TEXTURE_MAX_LEVEL, rec.levels.length - 1);
  }
  gl.texParameteri(target, gl.TEXTURE_MIN_FILTER, min);
  return {uniform: rec.uniform, target, texture: tex};
}

// an 8-bit sRGB image as an SRGB8_ALPHA8 texture: sampling decodes to linear before filtering
function imageTexture(gl, rec, bitmap) {
  const tex = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, tex);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.SRGB8_ALPHA8, gl.RGBA, gl.UNSIGNED_BYTE, bitmap);
  const filter = rec.filter === "linear" ? gl.LINEAR : gl.NEAREST;
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, filter);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, filter);
  for (const p of [gl.TEXTURE_WRAP_S, gl.TEXTURE_WRAP_T]) gl.texParameteri(gl.TEXTURE_2D, p, gl.CLAMP_TO_EDGE);
  return {uniform: rec.uniform, target: gl.TEXTURE_2D, texture: tex};
}

function uniformBlocks(gl, blocks, data) {
  return blocks.map((b) => {
    const buffer = gl.createBuffer();
    gl.bindBuffer(gl.UNIFORM_BUFFER, buffer);
    gl.bufferData(gl.UNIFORM_BUFFER, new Uint8Array(data, b.data[0], b.data[1]), gl.STATIC_DRAW);
    return {name: b.name, buffer};
  });
}

function renderTarget(gl, width, height, formats, depth = false) {
  const fb = gl.createFramebuffer();
  gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
  const textures = formats.map((f, k) => {
    const [internal, format, type] = TARGETS[f];
    const tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.texStorage2D(gl.TEXTURE_2D, 1, internal, width, height);
    for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D, p, gl.NEAREST);
    for (const p of [gl.TEXTURE_WRAP_S, gl.TEXTURE_WRAP_T]) gl.texParameteri(gl.TEXTURE_2D, p, gl.CLAMP_TO_EDGE);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0 + k, gl.TEXTURE_2D, tex, 0);
    return {target: gl.TEXTURE_2D, texture: tex, format, type};
  });
  if (depth) {
    const rb = gl.createRenderbuffer();
    gl.bindRenderbuffer(gl.RENDERBUFFER, rb);
    gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT24, width, height);
    gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, rb);
  }
  gl.drawBuffers(formats.map((_, k) => gl.COLOR_ATTACHMENT0 + k));
  const status = gl.checkFramebufferStatus(gl.FRAMEBUFFER);
  if (status !== gl.FRAMEBUFFER_COMPLETE) {
    throw new WebGLError(`render target ${width}x${height} (${formats.join(", ")}): incomplete (0x${status.toString(16)})`);
  }
  return {fb, textures, width, height, depth};
}

// Binds samplers (by uniform name, consecutive units) and uniform blocks (by block name) a program uses.
function bindResources(gl, prog, textures, blocks = []) {
  let unit = 0;
  for (const t of textures) {
    if (!prog.uniforms[t.uniform]) continue;
    gl.activeTexture(gl.TEXTURE0 + unit);
    gl.bindTexture(t.target, t.texture);
    gl.uniform1i(prog.uniforms[t.uniform].location, unit++);
  }
  blocks.forEach((b, k) => {
    const index = gl.getUniformBlockIndex(prog.program, b.name);
    if (index === gl.INVALID_INDEX) return;
    gl.uniformBlockBinding(prog.program, index, k);
    gl.bindBufferBase(gl.UNIFORM_BUFFER, k, b.buffer);
  });
}

// --- cameras (scene/camera.py) -------------------------------------------------------------------

const radians = (d) => d * Math.PI / 180;
const sub = (a, b) => a.map((x, i) => x - b[i]);
const dot = (a, b) => a.reduce((s, x, i) => s + x * b[i], 0);
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const normalize = (a) => { const n = Math.hypot(...a); return a.map((x) => x / n); };

function direction(yaw, pitch) {
  const y = radians(yaw), p = radians(pitch);
  return [-Math.sin(y) * Math.cos(p), Math.sin(p), -Math.cos(y) * Math.cos(p)];
}

// pyrr's matrices: row-vector layout (v @ M), row-major arrays: GLSL's column-major M * v as they are
function lookAt(eye, target, up) {
  const f = normalize(sub(target, eye)), s = normalize(cross(f, up)), u = normalize(cross(s, f));
  return [s[0], u[0], -f[0], 0, s[1], u[1], -f[1], 0, s[2], u[2], -f[2], 0, -dot(s, eye), -dot(u, eye), dot(f, eye), 1];
}

function perspective(fovY, aspect, near, far) {
  const ymax = near * Math.tan(fovY * Math.PI / 360), xmax = ymax * aspect;
  const e = near / xmax, f = near / ymax, c = -(far + near) / (far - near), d = -2 * far * near / (far - near);
  return [e, 0, 0, 0, 0, f, 0, 0, 0, 0, c, -1, 0, 0, d, 0];
}

function multiply(a, b) {   // row-major 4x4: a @ b
  const out = new Array(16).fill(0);
  for (let i = 0; i < 4; ++i) for (let j = 0; j < 4; ++j) for (let k = 0; k < 4; ++k) out[4 * i + j] += a[4 * i + k] * b[4 * k + j];
  return out;
}

function invert(m) {   // Gauss-Jordan with partial pivoting, float64
  const a = [...Array(4)].map((_, i) => [...m.slice(4 * i, 4 * i + 4), ...[0, 1, 2, 3].map((j) => +(i === j))]);
  for (let c = 0; c < 4; ++c) {
    let p = c;
    for (let r = c + 1; r < 4; ++r) if (Math.abs(a[r][c]) > Math.abs(a[p][c])) p = r;
    [a[c], a[p]] = [a[p], a[c]];
    const d = a[c][c];
    for (let j = 0; j < 8; ++j) a[c][j] /= d;
    for (let r = 0; r < 4; ++r) {
      if (r === c) continue;
      const f = a[r][c];
      for (let j = 0; j < 8; ++j) a[r][j] -= f * a[c][j];
    }
  }
  return a.flatMap((row) => row.slice(4));
}

export class Camera {
  constructor(record) { this.initial = JSON.parse(JSON.stringify(record)); this.reset(); }
  reset() { Object.assign(this, JSON.parse(JSON.stringify(this.initial))); }
  get is3d() { return this.type !== "plane2d"; }

  scale(w, h) {
    const a = w / h;
    if (a >= this.aspect) { const ey = 1 / this.zoom; return [ey * a / this.aspect, ey]; }
    const ex = 1 / this.zoom;
    return [ex, ex * this.aspect / a];
  }
  view2d(w, h) { const [ex, ey] = this.scale(w, h); return [this.center[0] - 0.5 * ex, this.center[1] - 0.5 * ey, ex, ey]; }
  eye() { return this.type === "orbit" ? sub(this.target, direction(this.yaw, this.pitch).map((x) => x * this.distance)) : this.position; }
  viewMatrix() {
    const eye = this.eye();
    const target = this.type === "orbit" ? this.target : eye.map((x, i) => x + direction(this.yaw, this.pitch)[i]);
    return lookAt(eye, target, [0, 1, 0]);
  }
  projection(w, h) { return perspective(this.fov_y, w / h, this.near, this.far); }

  // the uniforms scene/camera.py's uniforms(width, height) gives
  uniforms(w, h) {
    if (!this.is3d) return {u_view: this.view2d(w, h)};
    const view = this.viewMatrix(), proj = this.projection(w, h);
    return {u_view_matrix: view, u_proj: proj, u_inv_view_proj: invert(multiply(view, proj)), u_eye: this.eye()};
  }

  drag(dx, dy, w, h, pan) {
    if (!this.is3d) {
      const [ex, ey] = this.scale(w, h);
      this.center = [this.center[0] - dx / w * ex, this.center[1] + dy / h * ey];
    } else if (this.type === "fly") {
      this.yaw = ((this.yaw + dx * (this.look_speed ?? 0.2)) % 360 + 360) % 360;
      this.pitch = Math.max(-89, Math.min(89, this.pitch - dy * (this.look_speed ?? 0.2)));
    } else if (pan) {
      const perPx = 2 * this.distance * Math.tan(radians(this.fov_y) / 2) / h;
      const fwd = direction(this.yaw, this.pitch), right = normalize(cross(fwd, [0, 1, 0])), up = cross(right, fwd);
      this.target = this.target.map((t, i) => t + perPx * (-dx * right[i] + dy * up[i]));
    } else {
      const speed = this.orbit_speed ?? 0.3, maxPitch = this.max_pitch ?? 89;
      this.yaw = ((this.yaw + dx * speed) % 360 + 360) % 360;
      this.pitch = Math.max(-maxPitch, Math.min(maxPitch, this.pitch - dy * speed));
    }
  }

  // a fly camera's step (scene/camera.py FlyCamera.move): forward, right, up in [-1, 1], dt seconds
  move(forward, right, up, dt) {
    const f = direction(this.yaw, this.pitch), r = normalize(cross(f, [0, 1, 0])), step = (this.speed ?? 1) * dt;
    this.position = this.position.map((p, i) => p + step * (forward * f[i] + right * r[i] + (i === 1 ? up : 0)));
  }

  wheel(factor, x, y, w, h) {
    if (!this.is3d) {
      const [ox, oy, sx, sy] = this.view2d(w, h);
      const before = [ox + x / w * sx, oy + (h - y) / h * sy];
      this.zoom = Math.max(this.min_zoom ?? 0.05, Math.min(this.max_zoom ?? 512, this.zoom / factor));
      const [ox2, oy2, sx2, sy2] = this.view2d(w, h);
      const after = [ox2 + x / w * sx2, oy2 + (h - y) / h * sy2];
      this.center = [this.center[0] + before[0] - after[0], this.center[1] + before[1] - after[1]];
    } else if (this.type === "orbit") {
      this.distance = Math.max(1e-4, Math.min(1e6, this.distance * factor));
    } else {
      const f = direction(this.yaw, this.pitch), step = (factor - 1) * -4 * (this.speed ?? 1);
      this.position = this.position.map((p, i) => p + step * f[i]);
    }
  }
}

// --- the viewer ----------------------------------------------------------------------------------

// The WebGL2 side of the viewer's passes: what Viewer asks of a GPU (webgpu_backend.js is the other).
// A pass draws ``program`` into ``target`` (null: the canvas) over ``size`` (its lower-left corner), with
// textures bound by uniform name, uniform blocks by block name, the uniforms by name, and either the
// full-screen triangle or a mesh (``geometry``, depth-tested).
export class GLBackend {
  constructor(canvas, manifest, compiled, sources) {
    const gl = this.gl = compiled ? compiled.gl : createContext(canvas, manifest);
    this.programs = compiled ? compiled.programs
      : Object.fromEntries(Object.entries(sources).map(([name, src]) => [name, compile(gl, name, src)]));
    this.vao = gl.createVertexArray();   // the full-screen triangle needs no attributes
    this.api = "webgl2";
    this.yDown = false;                  // the canvas's row 0 is its bottom one
  }

  texture(rec, data) { return texture(this.gl, rec, data); }
  imageTexture(rec, bitmap) { return imageTexture(this.gl, rec, bitmap); }
  blocks(blocks, data) { return uniformBlocks(this.gl, blocks, data); }
  target(width, height, formats, depth = false) { return renderTarget(this.gl, width, height, formats, depth); }

  geometry(program, mesh, data) {
    const gl = this.gl, prog = this.programs[program];
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    for (const [name, a] of Object.entries(mesh.attributes)) {
      const location = gl.getAttribLocation(prog.program, name);
      if (location < 0) continue;
      const buffer = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
      gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(data, a.data[0], a.data[1] / 4), gl.STATIC_DRAW);
      gl.enableVertexAttribArray(location);
      gl.vertexAttribPointer(location, a.size, gl.FLOAT, false, 0, 0);
    }
    if (mesh.indices) {
      const buffer = gl.createBuffer();
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, buffer);
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, new Uint32Array(data, mesh.indices[0], mesh.indices[1] / 4), gl.STATIC_DRAW);
    }
    gl.bindVertexArray(null);
    return {vao, count: mesh.count, indexed: !!mesh.indices};
  }

  // every colour attachment of ``target`` to ``colour`` (integer ones to 0), its depth to 1
  clear(target, colour = [0, 0, 0, 0]) {
    const gl = this.gl;
    gl.bindFramebuffer(gl.FRAMEBUFFER, target.fb);
    target.textures.forEach((t, k) => {
      if (t.format === gl.RED_INTEGER) gl.clearBufferuiv(gl.COLOR, k, new Uint32Array(4));
      else gl.clearBufferfv(gl.COLOR, k, new Float32Array(colour));
    });
    if (target.depth) gl.clearBufferfi(gl.DEPTH_STENCIL, 0, 1.0, 0);
  }

  draw(program, target, {textures = [], blocks = [], uniforms = {}, size, geometry = null}) {
    const gl = this.gl, prog = this.programs[program];
    gl.useProgram(prog.program);
    bindResources(gl, prog, textures, blocks);
    for (const [name, value] of Object.entries(uniforms)) setUniform(gl, prog, name, value);
    gl.bindFramebuffer(gl.FRAMEBUFFER, target ? target.fb : null);
    gl.viewport(0, 0, size[0], size[1]);
    gl.disable(gl.BLEND); gl.disable(gl.CULL_FACE);
    if (geometry) {
      gl.enable(gl.DEPTH_TEST); gl.depthFunc(gl.LESS);
      gl.bindVertexArray(geometry.vao);
      if (geometry.indexed) gl.drawElements(gl.TRIANGLES, geometry.count, gl.UNSIGNED_INT, 0);
      else gl.drawArrays(gl.TRIANGLES, 0, geometry.count);
    } else {
      gl.disable(gl.DEPTH_TEST);
      gl.bindVertexArray(this.vao);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
    }
  }

  finish() {   // waits for the frame
    const gl = this.gl;
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
    const error = gl.getError();
    if (error !== gl.NO_ERROR) throw new WebGLError(`drawing: GL error 0x${error.toString(16)}`);
  }

  settled() { return settled(this.gl); }

  // the canvas's lower-left w x h as 8-bit RGBA, rows top to bottom
  pixels(w, h) {
    const gl = this.gl, raw = new Uint8Array(w * h * 4);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, raw);
    const flipped = new Uint8Array(raw.length);
    for (let y = 0; y < h; ++y) flipped.set(raw.subarray((h - 1 - y) * w * 4, (h - y) * w * 4), y * w * 4);
    return flipped;
  }
}

export class Viewer {
  // ``gpu``: a backend made beforehand (main compiles with progress), else a WebGL2 one made here.
  constructor(canvas, {manifest, data, sources, images}, {width, height} = {}, gpu = null) {
    this.manifest = manifest;
    this.width = width || manifest.size[0];
    this.height = height || manifest.size[1];
    this.canvasSize = [this.width, this.height];   // width, height: what a frame draws (less for a preview)
    this.drawing = Promise.resolve();   // the frame in flight: frames are drawn one after another
    canvas.width = this.width;
    canvas.height = this.height;
    this.gpu = gpu || new GLBackend(canvas, manifest, null, sources);
    this.textures = manifest.textures.map((t) => this.gpu.texture(t, data));
    this.blocks = this.gpu.blocks(manifest.blocks, data);
    const display = manifest.display;
    const ref = display.reference;
    this.reference = !ref ? null : ref.image ? this.gpu.imageTexture(ref, images[ref.image]) : this.gpu.texture(ref, data);
    this.camera = new Camera(manifest.camera);
    this.values = Object.fromEntries(manifest.settings.map((s) => [s.name, s.value]));
    this.mode = display.modes[display.mode] ?? 0;
    this.split = display.split;
    if (manifest.mesh) this.mesh = this._meshPass(manifest.mesh, data);
    const n = manifest.attachments, formats = Array(n).fill("rgba32f");
    const target = (f, depth = false) => this.gpu.target(this.width, this.height, f, depth);
    this.targets = {network: target(formats), output: target(["rgba32f"])};
    if (manifest.accumulate) {
      this.targets.sample = target(formats);
      this.targets.spare = target(formats);
    }
    this.samples = 0;
    this.key = null;
    this.frameMs = null;
  }

  get gl() { return this.gpu.gl; }

  _meshPass(mesh, data) {
    const geometry = this.gpu.geometry(mesh.program, mesh, data);
    const formats = mesh.targets.map((t) => t.format);
    const named = (target) => { target.textures.forEach((t, k) => { t.uniform = mesh.targets[k].uniform; }); return target; };
    const target = (f, depth = false) => this.gpu.target(this.width, this.height, f, depth);
    // BLEND surfaces peeled front to back (runtime/geometry.py draw_layer): two G-buffers in turn, the
    // scene pass over each into `shaded`, laid under the ones in front in `accum`, then over the opaque
    if (mesh.peel) {
      this.peel = {layers: mesh.peel, gbuffers: [0, 1].map(() => named(target(formats, true))),
                   shaded: target(["rgba32f"]), opaque: target(["rgba32f"]),
                   accum: [0, 1].map(() => target(["rgba32f"]))};
    }
    return {program: mesh.program, geometry, target: named(target(formats, true))};
  }

  // uniforms every pass may read: the manifest's, the camera's, the live settings'
  _uniforms() {
    const out = {...this.manifest.uniforms, u_size: [this.width, this.height], ...this.camera.uniforms(this.width, this.height)};
    for (const s of this.manifest.settings) {
      if (!s.uniform) continue;
      const v = this.values[s.name];
      out[s.uniform] = s.type === "choice" ? s.indices[s.choices.indexOf(v)] : s.type === "bool" ? +v : v;
    }
    return out;
  }

  // every pass a frame may draw and its target (null: the canvas), for a backend that makes its
  // pipelines before the first frame
  passes() {
    const m = this.manifest, p = m.programs, out = [];
    const into = m.accumulate ? this.targets.sample : this.targets.network;
    if (this.mesh) out.push({program: this.mesh.program, target: this.mesh.target, geometry: this.mesh.geometry});
    out.push({program: p.scene, target: this.peel ? this.peel.opaque : into});
    if (this.peel) out.push({program: p.blend_layer, target: this.peel.accum[0]}, {program: p.blend_resolve, target: into});
    if (m.accumulate) out.push({program: p.accumulate, target: this.targets.spare});
    out.push({program: p.display, target: this.targets.output}, {program: p.present, target: null});
    return out;
  }

  _pass(program, target, resources) {
    this.gpu.draw(program, target, {size: [this.width, this.height], ...resources});
  }

  // the scene pass (and the G-buffer before it), redrawn when its inputs change; a stochastic
  // program adds one sample per call to the running mean instead (runtime/renderer.py render_network)
  renderNetwork() {
    const m = this.manifest, uniforms = this._uniforms();
    const key = JSON.stringify([uniforms, this.width, this.height]);
    if (m.accumulate) {
      if (key !== this.key) this.samples = 0;
      if (this.samples >= SAMPLE_CAP) return;
      uniforms.u_sample_index = this.samples;
    } else if (key === this.key) {
      return;
    }
    let gbuffer = [];
    if (this.mesh) {
      this._gbuffer(this.mesh.target, this.peel ? 0 : -1, uniforms);
      gbuffer = this.mesh.target.textures;
    }
    const into = m.accumulate ? this.targets.sample : this.targets.network;
    this._scenePass(gbuffer, uniforms, this.peel ? this.peel.opaque : into);
    if (this.peel) this._peelLayers(uniforms, into);
    this.key = key;
    if (m.accumulate) this._fold();
    else this.samples = 1;
  }

  // the mesh's G-buffer into `target`: layer 0 the opaque surfaces (BLEND ones left to peel), -1 with
  // BLEND ones drawn opaque, k > 0 the k-th nearest BLEND surface (lib/gltf_cutout)
  _gbuffer(target, layer, uniforms, front = null) {
    this.gpu.clear(target);
    const peel = layer > 0 ? [{...this.mesh.target.textures[0], uniform: "u_peel_back"},
                              {...(front || this.mesh.target).textures[0], uniform: "u_peel_front"}] : [];
    // the material textures: MASK cut-outs, BLEND layers
    this._pass(this.mesh.program, target, {textures: [...this.textures, ...peel], geometry: this.mesh.geometry,
      uniforms: {u_view: uniforms.u_view_matrix, u_proj: uniforms.u_proj, u_gbuffer_layer: layer,
                 u_model: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}});
  }

  _scenePass(gbuffer, uniforms, target) {
    this._pass(this.manifest.programs.scene, target, {textures: [...this.textures, ...gbuffer], blocks: this.blocks,
                                                      uniforms});
  }

  _peelLayers(uniforms, into) {
    const p = this.peel, m = this.manifest;
    this.gpu.clear(p.accum[0], [0, 0, 0, 1]);
    let front = null;
    for (let k = 1; k <= p.layers; ++k) {
      const g = p.gbuffers[(k - 1) % 2];
      this._gbuffer(g, k, uniforms, front);
      this._scenePass(g.textures, uniforms, p.shaded);
      const targets = m.mesh.targets.map((t) => t.uniform);   // what passes/gltf_blend_layer reads of the layer
      const reads = m.mesh.layer_reads.map((n) => ({...g.textures[targets.indexOf(`u_gbuffer_${n}`)], uniform: `u_layer_${n}`}));
      this._pass(m.programs.blend_layer, p.accum[k % 2], {
        textures: [...this.textures, {...p.accum[(k - 1) % 2].textures[0], uniform: "u_accum"},
                   {...p.shaded.textures[0], uniform: "u_layer_colour"}, ...reads]});
      front = g;
    }
    this._pass(m.programs.blend_resolve, into, {textures: [{...p.accum[p.layers % 2].textures[0], uniform: "u_accum"},
                                                           {...p.opaque.textures[0], uniform: "u_opaque"}]});
  }

  _fold() {   // mean of n samples = mean of n - 1 + this one, ping-pong between two targets
    const {network: mean, spare, sample} = this.targets;
    this.samples += 1;
    const textures = [];
    mean.textures.forEach((t, k) => {
      textures.push({...t, uniform: `u_mean${k}`}, {...sample.textures[k], uniform: `u_sample${k}`});
    });
    this._pass(this.manifest.programs.accumulate, spare, {textures, uniforms: {u_count: this.samples}});
    this.targets.network = spare;
    this.targets.spare = mean;
  }

  // network pass (if stale) + display pass + present to the canvas; resolves to the frame's
  // milliseconds. ``preview``: every pass draws 1 / preview of the size (the lower-left corner of its
  // targets), shown enlarged: a first picture at a fraction of a full frame's cost. A frame asked for
  // while another is in flight (the page's loop, a caller's) is drawn after it: an asynchronous
  // backend's frames would otherwise share the viewer's size mid-frame.
  render({preview = 1} = {}) {
    const frame = this.drawing.then(() => this._frame(preview));
    this.drawing = frame.catch(() => {});
    return frame;
  }

  async _frame(preview) {
    const [w, h] = this.canvasSize;
    this.width = Math.ceil(w / preview);
    this.height = Math.ceil(h / preview);
    try {
      return await this._render();
    } finally {
      this.width = w;
      this.height = h;
    }
  }

  async _render() {
    const m = this.manifest, d = m.display;
    const start = performance.now();
    this.renderNetwork();
    const reference = this.reference ? [this.reference] : [];
    const uniforms = {u_exposure: d.exposure, u_error_scale: d.error_scale, ...this._uniforms(), u_mode: this.mode,
                      u_split: this.split, u_has_reference: +!!this.reference,
                      u_ref_view: d.reference_space === "field" && !this.camera.is3d ? this.camera.view2d(this.width, this.height)
                                                                                      : [0, 0, 1, 1]};
    this._pass(m.programs.display, this.targets.output,
               {textures: [{...this.targets.network.textures[0], uniform: "u_network"}, ...reference], uniforms});
    const [cw, ch] = this.canvasSize;
    // the frame fills the canvas's lower-left corner, enlarged by canvas / frame (1 at full size);
    // where the canvas's rows run top down, read bottom up
    const scale = [this.width / cw, this.height / ch];
    const present = this.gpu.yDown ? {u_origin: [0, ch], u_scale: [scale[0], -scale[1]]} : {u_origin: [0, 0], u_scale: scale};
    const pictured = d.tonemapped_modes.includes(this.mode);   // error views and raw lanes: 0, as they are
    for (const s of m.settings) {
      if (s.present) present[s.present] = pictured ? s.indices[s.choices.indexOf(this.values[s.name])] : 0;
    }
    this.gpu.draw(m.programs.present, null, {textures: [{...this.targets.output.textures[0], uniform: "u_source"}],
                                             uniforms: present, size: this.canvasSize});
    await this.gpu.finish();
    this.frameMs = performance.now() - start;
    return this.frameMs;
  }

  // the canvas as 8-bit sRGB RGBA, rows top to bottom, base64 (what a screenshot holds)
  async pixels() {
    return base64(await this.gpu.pixels(this.width, this.height));
  }
}

export function base64(bytes) {
  let s = "";
  for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  return btoa(s);
}

// --- the network evaluation page: passes/evaluate.frag over the exported batch --------------------

// ``repeats``: the batch drawn and read back that many times (inshade bench web), ``times`` the ms of each.
export function evaluate(canvas, {manifest, data, sources}, {repeats = 1} = {}) {
  const e = manifest.evaluate;
  const gl = createContext(canvas, manifest);
  const n = e.count, w = Math.min(n, 256), h = Math.ceil(n / w);
  const inputs = new Float32Array(data, e.inputs[0], e.inputs[1] / 4);
  const uint = new Set(e.uint_lanes);
  const floats = new Float32Array(w * h * e.in_blocks * 4), ids = new Uint32Array(w * h * Math.max(e.in_uint_blocks, 1) * 4);
  for (let i = 0; i < n; ++i) {
    let f = 0, u = 0;
    for (let j = 0; j < e.in_dim; ++j) {
      const x = inputs[i * e.in_dim + j];
      if (uint.has(j)) ids[i * e.in_uint_blocks * 4 + u++] = x;
      else floats[i * e.in_blocks * 4 + f++] = x;
    }
  }
  const input = (name, dtype, array, blocks) => texture(gl, {uniform: name, kind: "2d", size: [w * blocks, h, 1], channels: 4,
    dtype, filter: "nearest", wrap: "clamp", levels: [[array.byteOffset, array.byteLength]]}, array.buffer);
  const textures = [input("u_inputs", "f4", floats, e.in_blocks)];
  if (e.uint_lanes.length) textures.push(input("u_inputs_uint", "u4", ids, e.in_uint_blocks));
  textures.push(...e.textures.map((t) => texture(gl, t, data)));
  const blocks = uniformBlocks(gl, e.blocks, data);
  const programs = e.passes.map((name) => compile(gl, name, sources[name]));   // at most 4 output blocks each
  const per = e.blocks_per_pass;
  const targets = programs.map((_, k) => renderTarget(gl, w, h, Array(Math.min(per, e.out_blocks - k * per)).fill("rgba32f")));
  gl.bindVertexArray(gl.createVertexArray());
  const times = [];
  let out;
  for (let r = 0; r < repeats; ++r) {
    const start = performance.now();
    out = [];
    programs.forEach((prog, k) => {
      gl.useProgram(prog.program);
      bindResources(gl, prog, textures, blocks);
      gl.bindFramebuffer(gl.FRAMEBUFFER, targets[k].fb);
      gl.viewport(0, 0, w, h);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
      targets[k].textures.forEach((_, b) => {
        gl.readBuffer(gl.COLOR_ATTACHMENT0 + b);
        const block = new Float32Array(w * h * 4);
        gl.readPixels(0, 0, w, h, gl.RGBA, gl.FLOAT, block);
        out.push(block);
      });
    });
    times.push(performance.now() - start);
  }
  const ms = times[0];
  const outputs = new Float32Array(n * e.out_dim);
  for (let i = 0; i < n; ++i) for (let j = 0; j < e.out_dim; ++j) outputs[i * e.out_dim + j] = out[j >> 2][i * 4 + (j & 3)];
  const error = gl.getError();
  if (error !== gl.NO_ERROR) throw new WebGLError(`evaluating: GL error 0x${error.toString(16)}`);
  return {gl, outputs, count: n, outDim: e.out_dim, ms, times, base64: base64(new Uint8Array(outputs.buffer))};
}

// --- controls ------------------------------------------------------------------------------------

function control(setting, value, onChange) {
  const label = document.createElement("label");
  label.textContent = setting.label + " ";
  let input;
  if (setting.type === "choice") {
    input = document.createElement("select");
    for (const c of setting.choices) input.add(new Option(c, c, false, c === value));
    input.onchange = () => onChange(input.value);
  } else if (setting.type === "bool") {
    input = document.createElement("input");
    input.type = "checkbox";
    input.checked = !!value;
    input.onchange = () => onChange(input.checked);
  } else {
    input = document.createElement("input");
    input.type = "range";
    input.min = setting.min ?? 0;
    input.max = setting.max ?? 1;
    input.step = setting.type === "int" ? 1 : (input.max - input.min) / 1000;
    input.value = value;
    const shown = document.createElement("output");
    shown.textContent = value;
    input.oninput = () => { shown.textContent = input.value; onChange(Number(input.value)); };
    label.append(input, shown);
  }
  if (!label.contains(input)) label.append(input);
  if (setting.fixed) { input.disabled = true; label.title = setting.fixed; label.classList.add("fixed"); }
  return label;
}

// The GPU the page draws with, for the API loadExport chose; ``progress(text)`` says how far compiling is.
async function backend(canvas, loaded, progress) {
  if (loaded.api === "webgpu") {
    const {WebGPUBackend} = await import("./webgpu_backend.js");
    return WebGPUBackend.create(canvas, loaded, progress);
  }
  const gl = createContext(canvas, loaded.manifest);
  return new GLBackend(canvas, loaded.manifest, {gl, programs: await compileAll(gl, loaded.sources, progress)});
}

// index.html: the viewer with its controls, orbit / zoom / pan and a frame-time readout
export async function main({base = "./", canvas, panel, status} = {}) {
  const t0 = performance.now();
  const page = window.inshade = {ready: false, error: null, progress: []};
  try {
    const params = new URLSearchParams(location.search);
    const loaded = await loadExport(base, params.get("api") || "auto");
    const progress = (text) => {
      status.textContent = text;
      page.progress.push({ms: performance.now() - t0, text});
    };
    const gpu = await backend(canvas, loaded, progress);
    page.api = gpu.api;
    const viewer = new Viewer(canvas, loaded, {width: +params.get("width") || 0, height: +params.get("height") || 0}, gpu);
    if (gpu.prepare) await gpu.prepare(viewer.passes(), progress);
    page.viewer = viewer;
    document.title = `${loaded.manifest.title} · inshade`;
    let dirty = true;
    const redraw = () => { dirty = true; };
    buildPanel(panel, viewer, redraw);
    attachPointer(canvas, viewer, redraw);
    // the first picture at a quarter of the size, shown before the full frame is drawn
    await viewer.render({preview: PREVIEW});
    page.firstFrameMs = performance.now() - t0;
    page.previewScale = PREVIEW;
    status.textContent = `first frame at 1/${PREVIEW} size after ${page.firstFrameMs.toFixed(0)} ms; drawing the full frame`;
    page.progress.push({ms: page.firstFrameMs, text: status.textContent});
    await gpu.settled();
    await viewer.render();
    page.fullFrameMs = performance.now() - t0;
    await gpu.settled();
    dirty = false;   // the full frame is on the canvas
    page.ready = true;
    const tick = async () => {
      if (dirty || (viewer.manifest.accumulate && viewer.samples < SAMPLE_CAP)) {
        dirty = false;
        await viewer.render();
        status.textContent = `${viewer.width}x${viewer.height} · ${gpu.api} · frame ${viewer.frameMs.toFixed(1)} ms` +
          (viewer.manifest.accumulate ? ` · ${viewer.samples} spp` : "") +
          ` · first frame ${page.firstFrameMs.toFixed(0)} ms, full ${page.fullFrameMs.toFixed(0)} ms after load`;
      }
      requestAnimationFrame(tick);
    };
    requestAnimationFrame(tick);
  } catch (err) {
    page.error = String(err.message || err);
    status.textContent = `error: ${page.error}`;
    status.classList.add("error");
    console.error(err);
  }
}

function buildPanel(panel, viewer, redraw) {
  const m = viewer.manifest, d = m.display;
  if (d.reference) {
    const modes = {type: "choice", label: "view", choices: Object.keys(d.modes)};
    panel.append(control(modes, Object.keys(d.modes).find((k) => d.modes[k] === viewer.mode),
                         (v) => { viewer.mode = d.modes[v]; redraw(); }));
    panel.append(control({type: "float", label: "split", min: 0, max: 1}, viewer.split,
                         (v) => { viewer.split = v; redraw(); }));
  }
  for (const s of m.settings) {
    panel.append(control(s, viewer.values[s.name], (v) => { viewer.values[s.name] = v; redraw(); }));
  }
  const reset = document.createElement("button");
  reset.textContent = "reset view";
  reset.onclick = () => { viewer.camera.reset(); redraw(); };
  panel.append(reset);
}

const FLY_KEYS = {KeyW: [1, 0, 0], KeyS: [-1, 0, 0], KeyD: [0, 1, 0], KeyA: [0, -1, 0], KeyE: [0, 0, 1], KeyQ: [0, 0, -1]};

function attachPointer(canvas, viewer, redraw) {
  let last = null;
  if (viewer.camera.type === "fly") {   // W A S D Q E move, 1/30 s per key repeat
    window.addEventListener("keydown", (e) => {
      const step = FLY_KEYS[e.code];
      if (!step) return;
      viewer.camera.move(...step, 1 / 30);
      redraw();
    });
  }
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  canvas.addEventListener("pointerdown", (e) => { last = [e.clientX, e.clientY]; canvas.setPointerCapture(e.pointerId); });
  canvas.addEventListener("pointerup", () => { last = null; });
  canvas.addEventListener("pointermove", (e) => {
    if (!last) return;
    const scale = viewer.width / canvas.clientWidth;
    viewer.camera.drag((e.clientX - last[0]) * scale, (e.clientY - last[1]) * scale, viewer.width, viewer.height,
                       e.buttons === 2 || e.buttons === 4 || e.shiftKey);
    last = [e.clientX, e.clientY];
    redraw();
  });
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    const r = canvas.getBoundingClientRect(), scale = viewer.width / r.width;
    viewer.camera.wheel(Math.exp(e.deltaY * 0.001), (e.clientX - r.left) * scale, (e.clientY - r.top) * scale,
                        viewer.width, viewer.height);
    redraw();
  }, {passive: false});
}
