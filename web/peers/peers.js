// inshade bench web: the exported network's batch through inshade's two evaluation pages, ONNX
// Runtime Web and TensorFlow.js, each timed (median of ?repeats after a warm-up) and its outputs
// handed back for the comparison with torch (web/bench_peers.py).
import { base64, evaluate, loadExport } from "./inshade.js";
import { evaluateWebGPU } from "./webgpu.js";

const out = document.getElementById("out");
const page = window.inshade = {ready: false, error: null, results: {}};
const repeats = +new URLSearchParams(location.search).get("repeats") || 5;

function f32(b64) {
  const bin = atob(b64), bytes = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; ++i) bytes[i] = bin.charCodeAt(i);
  return new Float32Array(bytes.buffer);
}

async function timed(run) {   // run() -> Float32Array; one warm-up, then `repeats` timed runs
  let y = await run();
  const times = [];
  for (let r = 0; r < repeats; ++r) {
    const t0 = performance.now();
    y = await run();
    times.push(performance.now() - t0);
  }
  return {times, base64: base64(new Uint8Array(y.buffer, y.byteOffset, y.byteLength))};
}

async function onnxruntime(ep, x, n) {
  ort.env.wasm.wasmPaths = new URL("node_modules/onnxruntime-web/dist/", location.href).href;
  const session = await ort.InferenceSession.create("model.onnx", {executionProviders: [ep]});
  const input = new ort.Tensor("float32", x, [n, 2]);
  const r = await timed(async () => (await session.run({x: input})).y.getData());
  return {...r, device: `onnxruntime-web ${ort.env.versions?.web ?? ""} ${ep}`};
}

async function tfjs(backend, x, n, net) {
  if (backend === "wasm") tf.wasm.setWasmPaths(new URL("node_modules/@tensorflow/tfjs-backend-wasm/dist/", location.href).href);
  if (!(await tf.setBackend(backend))) throw new Error(`TF.js: no ${backend} backend here`);
  await tf.ready();
  const layers = net.layers.map((l) => ({w: tf.tensor2d(f32(l.w), [l.out, l.in]).transpose(), b: tf.tensor1d(f32(l.b)), act: l.act}));
  const scales = Array.from({length: net.n_freqs}, (_, k) => Math.fround(2 ** k * Math.PI));
  const input = tf.tensor2d(x, [n, 2]);
  const forward = () => tf.tidy(() => {
    const parts = [...(net.include_input ? [input] : []), ...scales.map((s) => tf.sin(input.mul(s))),
                   ...scales.map((s) => tf.cos(input.mul(s)))];
    let h = tf.concat(parts, 1);
    for (const l of layers) {
      h = tf.add(tf.matMul(h, l.w), l.b);
      if (l.act === "relu") h = tf.relu(h);
    }
    return h;
  });
  const r = await timed(async () => { const y = forward(); const data = await y.data(); y.dispose(); return data; });
  return {...r, device: `tfjs ${tf.version.tfjs} ${backend}`};
}

try {
  const loaded = await loadExport("./");
  const e = loaded.manifest.evaluate, n = e.count;
  const x = new Float32Array(loaded.data, e.inputs[0], e.inputs[1] / 4);
  const net = await (await fetch("tfjs.json")).json();
  const runs = {
    "inshade WebGL2": async () => {
      const r = evaluate(document.getElementById("canvas"), loaded, {repeats: repeats + 1});
      const info = r.gl.getExtension("WEBGL_debug_renderer_info");
      return {times: r.times.slice(1), base64: r.base64,
              device: `WebGL2 ${r.gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : r.gl.RENDERER)}`};
    },
    "inshade WebGPU": async () => {
      const r = await evaluateWebGPU(loaded, {repeats: repeats + 1});
      return {times: r.times.slice(1), base64: r.base64, device: `WebGPU ${r.adapter}`};
    },
    "onnxruntime-web wasm": () => onnxruntime("wasm", x, n),
    "onnxruntime-web webgpu": () => onnxruntime("webgpu", x, n),
    "tfjs webgl": () => tfjs("webgl", x, n, net),
    "tfjs wasm": () => tfjs("wasm", x, n, net),
    "tfjs webgpu": () => tfjs("webgpu", x, n, net),
  };
  for (const [name, run] of Object.entries(runs)) {
    out.textContent = `running ${name}…`;
    try {
      page.results[name] = await run();
    } catch (err) {
      page.results[name] = {error: String(err.message || err)};
    }
  }
  out.textContent = JSON.stringify(Object.fromEntries(Object.entries(page.results).map(
    ([k, v]) => [k, v.error ?? `${(v.times.reduce((a, b) => a + b) / v.times.length).toFixed(1)} ms`])), null, 1);
  page.ready = true;
} catch (err) {
  page.error = String(err.message || err);
  out.textContent = `error: ${page.error}`;
}
