"""toy_noise: a test-only stochastic technique (tests/runtime/test_accumulation.py). Its program accumulates
(ProgramSpec.accumulate): each draw writes one sample of shaders/lib/random.glsl per pixel, so
the runtime's running mean can be checked against inshade/random.py. Attachment 0 is
(gain * random_uniform3(stream 0), 1), attachment 1 is (random_uniform3(stream 1), u of the pixel
centre under the camera).

The scene contract needs a network, so the asset carries a tiny one that the program ignores."""
import json
from pathlib import Path

import numpy as np

from inshade.bundle import Bundle
from inshade.technique import ProgramSpec, Technique

TECHNIQUE = Technique(
    name="toy_noise",
    summary="a test-only technique: uniform noise averaged over frames",
    kinds=("toy_noise",),
    programs=(ProgramSpec("passes/toy_noise.frag", attachments=2, bundle_kinds=("toy_noise",), accumulate=True),),
    shaders=Path(__file__).resolve().parent / "shaders",
)


def write(out, size=(8, 6)) -> Path:
    """The toy asset: a 2 -> 3 dense bundle (unused by the program) and its scene.json."""
    out = Path(out)
    rng = np.random.default_rng(0)
    meta = {"format": "inshade.bundle", "version": 1, "kind": "toy_noise", "name": out.name,
            "inputs": [{"name": "uv", "dim": 2, "semantic": "uv"}],
            "nodes": [{"id": "l0", "type": "dense", "inputs": ["uv"], "params": {"out": 3, "bias": True}}],
            "outputs": [{"name": "rgb", "node": "l0", "semantic": "linear_rgb"}]}
    Bundle(meta, {"l0.weight": rng.normal(size=(3, 2)).astype(np.float32),
                  "l0.bias": np.zeros(3, np.float32)}).save(out)
    scene = {"format": "inshade.scene", "version": 1, "name": out.name, "program": "passes/toy_noise.frag",
             "size": list(size), "networks": [{"bundle": ".", "output": "rgb"}],
             "camera": {"type": "plane2d"},
             "settings": {"gain": {"type": "float", "default": 1.0, "min": 0.0, "max": 2.0, "uniform": "u_gain"}}}
    (out / "scene.json").write_text(json.dumps(scene, indent=2) + "\n")
    return out
