"""A Wavefront OBJ + MTL + PNG texture made at test time (a rounded duck-like blob with a saturated yellow,
patterned base colour), and its conversion to .glb by obj2gltf (npm ``obj2gltf``, pinned in
tests/gltf_tools/package.json; ``npm ci --prefix tests/gltf_tools``): a glTF file as a common
third-party converter writes it. Nothing is downloaded: the pattern is scikit-image's bundled brick
photograph (``skimage.data.brick``, shipped inside the package).
"""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np

TOOLS = Path(__file__).resolve().parent / "gltf_tools"
OBJ2GLTF = TOOLS / "node_modules" / "obj2gltf" / "bin" / "obj2gltf.js"
# the duck's base colour: saturated yellow, sRGB (255, 216, 0), darkened / lightened by the pattern
DUCK_YELLOW = (255, 216, 0)
# the MTL's Blinn-Phong numbers; obj2gltf turns them into metallic 0, roughness 1 - Ns / 1000 = 0.5
DUCK_MTL = {"Kd": (1.0, 1.0, 1.0), "Ks": (0.5, 0.5, 0.5), "Ns": 500.0}


def duck_mesh(segments: int = 32) -> dict[str, np.ndarray]:
    """A duck-like blob of three closed uv spheres that overlap (as a modeller's quick duck is made): an
    ellipsoid body with a tail bump behind (-x), a round head up and forward (+x), a flattened beak.
    {"vertices" [V, 3], "uv" [V, 2] (v up, as OBJ's vt), "normals" [V, 3] (unit, welded across each
    part's uv seam), "faces" [F, 3] (counter-clockwise seen from outside)}."""
    from inshade.geometry.mesh import shading_normals
    from inshade.geometry.shapes import sphere

    tail = np.array([-0.93, 0.37, 0.0]) / np.linalg.norm([-0.93, 0.37, 0.0])
    parts = []
    for centre, radii, bump in (((0.0, 0.0, 0.0), (1.0, 0.62, 0.72), True),      # body
                                ((0.62, 0.72, 0.0), (0.42, 0.42, 0.42), False),  # head
                                ((1.0, 0.66, 0.0), (0.24, 0.07, 0.15), False)):  # beak
        ball = sphere(1.0, segments)
        d = np.asarray(ball.vertices, np.float64)
        v = d * np.asarray(radii)
        if bump:
            v = v + d * (0.3 * np.exp(-(1.0 - d @ tail) / 0.03))[:, None]
        ball.vertices = v + np.asarray(centre)
        parts.append((np.asarray(ball.vertices), np.asarray(ball.visual.uv, np.float64), shading_normals(ball),
                      np.asarray(ball.faces, np.int64)))
    offsets = np.cumsum([0] + [len(p[0]) for p in parts[:-1]])
    return {"vertices": np.concatenate([p[0] for p in parts]), "uv": np.concatenate([p[1] for p in parts]),
            "normals": np.concatenate([p[2] for p in parts]),
            "faces": np.concatenate([p[3] + o for p, o in zip(parts, offsets)])}


def duck_texture(size: int = 256) -> np.ndarray:
    """The duck's base colour, uint8 RGB [size, size, 3] (sRGB): DUCK_YELLOW scaled by 1 + 0.3 (b - mean b),
    b a brick photograph's brightness normalised to 0 .. 1 (clipped at 255)."""
    from skimage import data
    from skimage.transform import resize

    brick = resize(data.brick().astype(np.float64) / 255.0, (size, size), anti_aliasing=True)
    pattern = (brick - brick.min()) / max(float(np.ptp(brick)), 1e-12)       # 0 .. 1
    gain = 1.0 + 0.3 * (pattern - pattern.mean())
    rgb = np.asarray(DUCK_YELLOW, np.float64)[None, None, :] * gain[..., None]
    return np.clip(np.rint(rgb), 0, 255).astype(np.uint8)


def write_duck_obj(folder) -> Path:
    """duck.obj, duck.mtl and duck.png in ``folder``; returns the .obj's path."""
    from PIL import Image

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    mesh = duck_mesh()
    Image.fromarray(duck_texture()).save(folder / "duck.png")
    mtl = ["newmtl duck", *(f"{k} {' '.join(f'{x:.6g}' for x in np.atleast_1d(v))}" for k, v in DUCK_MTL.items()),
           "d 1", "illum 2", "map_Kd duck.png", ""]
    (folder / "duck.mtl").write_text("\n".join(mtl))
    lines = ["# a duck-like blob made by tests/obj_files.py", "mtllib duck.mtl", "o duck"]
    lines += [f"v {x:.7g} {y:.7g} {z:.7g}" for x, y, z in mesh["vertices"]]
    lines += [f"vt {u:.7g} {v:.7g}" for u, v in mesh["uv"]]
    lines += [f"vn {x:.7g} {y:.7g} {z:.7g}" for x, y, z in mesh["normals"]]
    lines += ["usemtl duck", "s 1"]
    lines += ["f " + " ".join(f"{i + 1}/{i + 1}/{i + 1}" for i in face) for face in mesh["faces"]]
    (folder / "duck.obj").write_text("\n".join(lines) + "\n")
    return folder / "duck.obj"


def obj_to_glb(obj_path, glb_path) -> Path:
    """Convert with obj2gltf's command line (``node .../obj2gltf.js -i OBJ -o GLB``): the MTL's Blinn-Phong
    material becomes a pbrMetallicRoughness one, the texture is embedded."""
    node = shutil.which("node")
    if node is None:
        raise RuntimeError("node is needed to run obj2gltf (Debian nodejs)")
    if not OBJ2GLTF.is_file():
        raise RuntimeError(f"obj2gltf is not installed: run npm ci --prefix {TOOLS}")
    glb_path = Path(glb_path)
    proc = subprocess.run([node, str(OBJ2GLTF), "-i", str(obj_path), "-o", str(glb_path)],
                          check=False, capture_output=True, text=True, timeout=300)
    if proc.returncode != 0 or not glb_path.is_file():
        raise RuntimeError(f"obj2gltf failed on {obj_path}: {proc.stderr.strip() or proc.stdout.strip()}")
    return glb_path


def duck_glb(folder) -> Path:
    """The duck written as OBJ + MTL + PNG in ``folder`` and converted to ``folder/duck.glb`` by obj2gltf."""
    folder = Path(folder)
    return obj_to_glb(write_duck_obj(folder), folder / "duck.glb")
