// window.threeRender(config) -> Promise of a glTF file drawn by three.js (WebGLRenderer, the
// MeshStandardMaterial / MeshPhysicalMaterial GLTFLoader makes), framed and lit as given.
//
// config: {
//   glb: the .glb as base64 (parsed by GLTFLoader.parseAsync: no file is placed anywhere),
//   width, height: pixels (pixel ratio 1, no antialiasing: each pixel is one sample at its centre),
//   view, projection: 4x4 matrices as 16 numbers in column-major order (Matrix4.fromArray),
//   position: the camera's position (the view matrix's inverse translation; checked against it),
//   lights: [{position: [x, y, z], intensity: candela, color: [r, g, b] linear}]: PointLight(color,
//           intensity, distance 0, decay 2), so irradiance = intensity / d^2 as inshade's point lights,
//   environment: "none" | "room" (RoomEnvironment through PMREMGenerator, sigma 0.04, as three's editor
//                and examples light a glTF), toneMapping: "none" | "neutral", exposure: number,
//   patches: optional, for diagnosis only: names of PATCHES below, each turning one of three.js's
//            departures from the glTF spec's appendix B off in its shader chunks (default: none) }
// resolves to {
//   linear: base64 float32 RGBA rows, bottom row first (GL order): the scene rendered into a FloatType
//           WebGLRenderTarget, linear sRGB, never tone mapped, cleared to transparent black (alpha 0
//           where no mesh is drawn),
//   srgb8: base64 uint8 RGBA rows, bottom row first: what three.js draws to the canvas (outputColorSpace
//          sRGB, toneMapping and exposure as asked), read back from the preserved drawing buffer,
//   width, height, revision (THREE.REVISION), renderer (the WebGL renderer string),
//   warnings: what three.js and its loader warned about while parsing and drawing (e.g. an extension
//             it does not support) }
// or rejects with the error.
import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
import { RoomEnvironment } from "three/addons/environments/RoomEnvironment.js";

let renderer = null;

function getRenderer() {
    if (renderer === null) {
        renderer = new THREE.WebGLRenderer({ antialias: false, alpha: true, preserveDrawingBuffer: true,
                                             premultipliedAlpha: true, powerPreference: "high-performance" });
        renderer.setPixelRatio(1);
        document.body.appendChild(renderer.domElement);
    }
    return renderer;
}

function fromBase64(text) {
    const bytes = atob(text);
    const out = new Uint8Array(bytes.length);
    for (let i = 0; i < bytes.length; ++i) out[i] = bytes.charCodeAt(i);
    return out;
}

function toBase64(view) {
    const bytes = new Uint8Array(view.buffer, view.byteOffset, view.byteLength);
    let text = "";
    for (let i = 0; i < bytes.length; i += 0x8000) text += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
    return btoa(text);
}

function rendererString(gl) {
    const ext = gl.getExtension("WEBGL_debug_renderer_info");
    return ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
}

const TONE_MAPPINGS = { none: THREE.NoToneMapping, neutral: THREE.NeutralToneMapping };

// Diagnosis: three.js r187's shader chunks edited back to what the glTF spec / inshade computes, one
// departure each: [chunk, text in it, replacement]. The text is matched with any run of white space
// standing for any other (the build drops blank lines); a text not found exactly once is an error.
const PATCHES = {
    // direct specular times 1 + F0 (1 / E_ss - 1) (Turquin's multiple-scattering energy compensation)
    no_multiscatter: [["lights_fragment_begin",
                       "material.multiScatteringCompensation = 1.0 + material.specularColorBlended * ( 1.0 / EssMs - 1.0 );",
                       "material.multiScatteringCompensation = vec3( 1.0 );"]],
    // roughness raised by the screen-space variation of the geometric normal (specular anti-aliasing)
    no_geometry_roughness: [["lights_physical_fragment", "material.roughness += geometryRoughness;", ""],
                            ["lights_physical_fragment", "material.clearcoatRoughness += geometryRoughness;", ""]],
    // the coat lobe weighted by Fresnel at n_c.v (as the blend that dims the base) instead of at v.h
    coat_fresnel_nv: [["lights_physical_pars_fragment", "vec3 F = F_Schlick( f0, f90, dotVH ); float V = V_GGX_SmithCorrelated( alpha, dotNL, dotNV );",
                       "vec3 F = F_Schlick( f0, f90, dotNV ); float V = V_GGX_SmithCorrelated( alpha, dotNL, dotNV );"]],
    // the Charlie sheen distribution at alpha = sheenRoughness (the extension's text) instead of its square
    sheen_alpha_linear: [["lights_physical_pars_fragment",
                          "float D_Charlie( float roughness, float dotNH ) { float alpha = pow2( roughness );",
                          "float D_Charlie( float roughness, float dotNH ) { float alpha = roughness;"]],
};

export function patchMaterial(material, names) {
    const edits = names.map((name) => {
        if (!(name in PATCHES)) throw new Error(`patch ${name}? (${Object.keys(PATCHES).join(", ")})`);
        return PATCHES[name];
    }).flat();
    material.customProgramCacheKey = () => `peer-patches:${names.join(",")}`;
    material.onBeforeCompile = (shader) => {
        const chunks = {};
        for (const [chunk, from, to] of edits) {
            const text = chunks[chunk] ?? THREE.ShaderChunk[chunk];
            const pattern = new RegExp(from.replace(/[.*+?^${}()|[\]\\]/g, "\\$&").replace(/\s+/g, "\\s*"), "g");
            const found = (text.match(pattern) || []).length;
            if (found !== 1) throw new Error(`three ${THREE.REVISION}: ${chunk} has "${from}" ${found} times, not once`);
            chunks[chunk] = text.replace(pattern, () => to);
        }
        for (const [chunk, text] of Object.entries(chunks)) {
            const include = `#include <${chunk}>`;
            if (!shader.fragmentShader.includes(include)) continue;   // e.g. an unlit material
            shader.fragmentShader = shader.fragmentShader.replace(include, text);
        }
    };
}

function dispose(root) {
    root.traverse((o) => {
        if (o.geometry) o.geometry.dispose();
        for (const m of [].concat(o.material || [])) {
            for (const value of Object.values(m)) if (value && value.isTexture) value.dispose();
            m.dispose();
        }
    });
}

async function threeRender(config) {
    const { width, height } = config;
    if (!(config.toneMapping in TONE_MAPPINGS)) throw new Error(`toneMapping: ${config.toneMapping}? (none, neutral)`);
    if (!["none", "room"].includes(config.environment)) throw new Error(`environment: ${config.environment}? (none, room)`);
    const warnings = [];
    const warn = console.warn;
    console.warn = (...args) => { warnings.push(args.map(String).join(" ")); warn.apply(console, args); };
    const r = getRenderer();
    const scene = new THREE.Scene();
    const target = new THREE.WebGLRenderTarget(width, height, { type: THREE.FloatType, format: THREE.RGBAFormat,
                                                                 colorSpace: THREE.LinearSRGBColorSpace,
                                                                 depthBuffer: true, samples: 0 });
    let environment = null;
    try {
        const gltf = await new GLTFLoader().parseAsync(fromBase64(config.glb).buffer, "");
        scene.add(gltf.scene);
        const patches = config.patches || [];
        if (patches.length) {
            gltf.scene.traverse((o) => { for (const m of [].concat(o.material || [])) patchMaterial(m, patches); });
        }

        const camera = new THREE.PerspectiveCamera();
        camera.matrixAutoUpdate = false;
        camera.matrix.fromArray(config.view).invert();          // the camera's world matrix
        camera.updateMatrixWorld(true);                          // matrixWorld, matrixWorldInverse = view
        camera.projectionMatrix.fromArray(config.projection);    // never updateProjectionMatrix(): kept as given
        camera.projectionMatrixInverse.copy(camera.projectionMatrix).invert();
        const eye = new THREE.Vector3().setFromMatrixPosition(camera.matrixWorld);
        const gap = eye.distanceTo(new THREE.Vector3().fromArray(config.position));
        if (!(gap <= 1e-4 * Math.max(1, eye.length()))) {
            throw new Error(`the view matrix puts the camera at ${eye.toArray()}, not at ${config.position}`);
        }

        for (const light of config.lights) {
            const colour = new THREE.Color().setRGB(...light.color, THREE.LinearSRGBColorSpace);
            const point = new THREE.PointLight(colour, light.intensity, 0, 2);
            point.position.fromArray(light.position);
            scene.add(point);
        }
        if (config.environment === "room") {
            const pmrem = new THREE.PMREMGenerator(r);
            environment = pmrem.fromScene(new RoomEnvironment(), 0.04).texture;
            pmrem.dispose();
            scene.environment = environment;
        }

        r.setSize(width, height, false);
        r.setClearColor(0x000000, 0);
        r.outputColorSpace = THREE.SRGBColorSpace;
        r.toneMappingExposure = config.exposure;

        // (a) linear: a render target is drawn in the working colour space, without tone mapping
        r.toneMapping = THREE.NoToneMapping;
        r.setRenderTarget(target);
        r.clear();
        r.render(scene, camera);
        const linear = new Float32Array(width * height * 4);
        r.readRenderTargetPixels(target, 0, 0, width, height, linear);

        // (b) the canvas: sRGB output, the tone mapping asked for
        r.setRenderTarget(null);
        r.toneMapping = TONE_MAPPINGS[config.toneMapping];
        r.clear();
        r.render(scene, camera);
        const gl = r.getContext();
        const srgb8 = new Uint8Array(width * height * 4);
        gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, srgb8);
        const error = gl.getError();
        if (error !== gl.NO_ERROR) throw new Error(`WebGL error 0x${error.toString(16)} reading the canvas`);
        if (gl.isContextLost()) throw new Error("the WebGL context was lost");

        dispose(gltf.scene);
        return { linear: toBase64(linear), srgb8: toBase64(srgb8), width, height, revision: THREE.REVISION,
                 renderer: rendererString(gl), warnings };
    } finally {
        console.warn = warn;
        target.dispose();
        if (environment) environment.dispose();
        r.setRenderTarget(null);
    }
}

window.threeRender = threeRender;
window.threeRevision = THREE.REVISION;
