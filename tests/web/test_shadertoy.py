"""A network as a Shadertoy Image pass: run as Shadertoy runs a pass (its uniforms and its main
around the pasted text, GLSL ES 3.00) on the GL driver against torch, and refused in one line when it
is no uv -> colour image or too big to paste."""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from inshade.codegen import LimitError
from inshade.codegen.targets import TargetError
from inshade.metrics import srgb_oetf
from inshade.models import GraphModule
from inshade.models.registry import TORCH_COMPONENTS
from inshade.web.shadertoy import (BACKGROUND, PASS_CHARS, SHOWN_RULE, _frag_uvs, _run, check_pass, image_pass,
                                   shown_colour, shown_output)


def image_bundle(widths, out_dim=3, semantic="linear_rgb", seed=0, freqs=3, render=True):
    torch.manual_seed(seed)
    g = GraphModule([("uv", 2, "uv")])
    src = g.add("enc", TORCH_COMPONENTS["frequency"](n_freqs=freqs), "uv")
    for i, w in enumerate(widths):
        src = g.add(f"a{i}", TORCH_COMPONENTS["sin" if i == 0 else "relu"](), g.dense(f"l{i}", src, w))
    g.output("rgb", g.dense(f"l{len(widths)}", src, out_dim), semantic)
    return g.export("image", "toy_image", render={"output": "rgb"} if render else None)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(widths=st.lists(st.sampled_from([4, 8, 16]), min_size=1, max_size=3), out_dim=st.sampled_from([1, 3, 4]),
       srgb=st.booleans(), seed=st.integers(0, 1000))
def test_pass_matches_torch_as_shadertoy_runs_it(gl, widths, out_dim, srgb, seed):
    bundle = image_bundle(widths, out_dim, "srgb" if srgb else "linear_rgb", seed)
    p = image_pass(bundle)
    assert "#version" not in p.text and "uniform" not in p.text   # Shadertoy writes both itself
    result = check_pass(p, GraphModule.from_bundle(bundle), bundle, ctx=gl)
    assert result.network.max_scaled <= 1e-5, result.lines()
    assert result.shown_max <= SHOWN_RULE, result.lines()
    assert result.ok


def test_the_picture_is_placed_and_encoded_as_a_display_shows_it(gl):
    """Independent of the check's own model: a network that outputs its uv as colour shows, on a
    wide view, the square centred with uv (0,0) bottom left, sRGB-encoded, the background beside."""
    g = GraphModule([("uv", 2, "uv")])
    dense = TORCH_COMPONENTS["dense"](2, 3, True)
    with torch.no_grad():
        dense.linear.weight.copy_(torch.tensor([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]))
        dense.linear.bias.zero_()
    g.add("l0", dense, "uv")
    g.output("rgb", "l0", "linear_rgb")
    p = image_pass(g.export("image", "uv_colour"))
    shown = _run(gl, p, 8, 4, network=False)   # data orientation: row 0 is the bottom
    assert np.allclose(shown[:, :2, :3], BACKGROUND) and np.allclose(shown[:, 6:, :3], BACKGROUND)
    centres = (np.arange(4) + 0.5) / 4
    expected_r = srgb_oetf(centres)
    assert np.allclose(shown[0, 2:6, 0], expected_r, atol=1e-5)         # u grows to the right
    assert np.allclose(shown[:, 2, 1], expected_r, atol=1e-5)           # v grows upwards
    assert np.allclose(shown[..., 3], 1.0)
    assert np.allclose(_frag_uvs(8, 4)[0, 2], [0.125, 0.125])


def test_refusals_are_one_line():
    sdf = GraphModule([("p", 3, "position")])
    sdf.output("d", sdf.dense("l0", "p", 1), "sdf")
    with pytest.raises(TargetError, match=r"^shadertoy: mainImage draws a network of one 2-lane float input \(uv\) "
                                          r"as an image; toy_sdf is p\[3\] -> d\[1\]$"):
        shown_output(sdf.export("sdf", "toy_sdf"))
    two = GraphModule([("uv", 2, "uv")])
    two.output("n", two.dense("l0", "uv", 2))
    with pytest.raises(TargetError, match=r"no output of 1, 3 or 4 lanes"):
        shown_output(two.export("x", "toy_two"))
    big = image_bundle([64, 64, 64])
    with pytest.raises(LimitError, match=rf"^shadertoy: the pass is \d+ characters \(\d+ weights as literals\); "
                                         rf"SHADERTOY_PASS_CHARS is {PASS_CHARS} \(inshade's budget"):
        image_pass(big)
    assert len(image_pass(big, limits={"SHADERTOY_PASS_CHARS": 10**7}).text) > PASS_CHARS


def test_a_network_reading_textures_is_refused():
    from inshade.bundle import load
    from inshade.scene.description import resolve_asset

    with pytest.raises(TargetError, match=r"^shadertoy: neural_image reads \d+ textures or blocks \(.*\) and a "
                                          r"pasted pass carries only literals; use --target es300"):
        image_pass(load(resolve_asset("neural_image")))


def test_cli_writes_checks_and_refuses(tmp_path, capsys):
    from inshade.cli import main

    def cli(*args):
        code = main(list(args))
        captured = capsys.readouterr()
        return code, captured.out, captured.err

    bundle = image_bundle([16, 16], 3, "srgb")
    bundle.save(tmp_path / "toy")
    toy, out = str(tmp_path / "toy"), tmp_path / "toy.glsl"
    code, stdout, err = cli("codegen", toy, "--target", "shadertoy", "--check", "-o", str(out))
    assert code == 0, err
    assert "shadertoy image pass:" in stdout and "sRGB-encoded, shown as is" in stdout
    assert "max |shadertoy - source| =" in stdout and "(rule 1e-05): ok" in stdout
    assert "as shown: max |pixel - torch's colour| =" in stdout
    text = out.read_text()
    assert "void mainImage(out vec4 fragColor, in vec2 fragCoord)" in text and "#include" not in text
    manifest = json.loads(out.with_suffix(".glsl.json").read_text())
    assert manifest["target"] == "shadertoy" and manifest["characters"] == len(text) and manifest["srgb"]
    # an existing file is kept without --force; the same bundle gives the same bytes
    code, _, err = cli("codegen", toy, "--target", "shadertoy", "-o", str(out))
    assert code == 2 and err == f"inshade: error: {out}: -o: exists; add --force to replace it\n"
    assert cli("codegen", toy, "--target", "shadertoy", "-o", str(out), "--force")[0] == 0
    assert out.read_text() == text
    code, stdout, _ = cli("codegen", toy, "--target", "shadertoy", "-o", "-")
    assert code == 0 and stdout == text
    code, _, err = cli("codegen", toy, "--target", "shadertoy", "--storage", "texture")
    assert code == 2 and "holds its weights as literals" in err and err.count("\n") == 1


PAGE = """<!doctype html><meta charset="utf-8"><canvas id="c" width="{w}" height="{h}"></canvas><script>
// The pass as Shadertoy's WebGL2 page runs it: its uniforms and main around the pasted text.
const src = {sources};
const gl = document.getElementById("c").getContext("webgl2", {{preserveDrawingBuffer: true, antialias: false}});
function shader(type, text) {{
  const s = gl.createShader(type); gl.shaderSource(s, text); gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
  return s;
}}
try {{
  const p = gl.createProgram();
  gl.attachShader(p, shader(gl.VERTEX_SHADER, src.vertex));
  gl.attachShader(p, shader(gl.FRAGMENT_SHADER, src.fragment));
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
  gl.useProgram(p);
  gl.uniform3f(gl.getUniformLocation(p, "iResolution"), {w}, {h}, 1);
  gl.bindVertexArray(gl.createVertexArray());
  gl.viewport(0, 0, {w}, {h});
  gl.drawArrays(gl.TRIANGLES, 0, 3);
  const px = new Uint8Array({w} * {h} * 4);
  gl.readPixels(0, 0, {w}, {h}, gl.RGBA, gl.UNSIGNED_BYTE, px);
  let bin = ""; for (let i = 0; i < px.length; ++i) bin += String.fromCharCode(px[i]);
  window.inshade = {{ready: true, pixels: btoa(bin)}};
}} catch (e) {{ window.inshade = {{error: String(e)}}; }}
</script>"""


def _in_chromium(p, w: int, h: int, folder) -> np.ndarray:
    """The pass drawn by headless Chromium's WebGL2 (ANGLE's GLSL ES validator, SwiftShader) as
    Shadertoy's page compiles it: 8-bit RGB [h, w, 3] in data orientation (row 0 = bottom)."""
    import base64

    from inshade.shaders import assemble
    from inshade.web.browser import Browser, serve

    sources = {"vertex": assemble("common/fullscreen.vert", version="es300").source,
               "fragment": assemble("passes/shadertoy.frag", version="es300",
                                    chunks={"shadertoy_pass": p.text}).source}
    (folder / "pass.html").write_text(PAGE.format(w=w, h=h, sources=json.dumps(sources)))
    with serve(folder) as url, Browser() as browser:
        state = browser.open(url + "pass.html", timeout=300)
        assert state.get("ready"), state
        pixels = browser.driver.execute_script("return window.inshade.pixels;")
    return np.frombuffer(base64.b64decode(pixels), np.uint8).reshape(h, w, 4)[..., :3]


def test_pass_runs_in_webgl2_as_on_shadertoy(tmp_path):
    """The pasted text in a browser's WebGL2: the picture within one 8-bit step of torch's colour."""
    bundle = image_bundle([16, 16], 3, "linear_rgb", seed=3)
    p = image_pass(bundle)
    w, h = 64, 48
    shown = _in_chromium(p, w, h, tmp_path) / 255.0
    uv = _frag_uvs(w, h)
    y = GraphModule.from_bundle(bundle)(torch.from_numpy(uv.reshape(-1, 2)))
    expected = shown_colour(y.detach().numpy().reshape(h, w, -1), p, uv)
    assert np.abs(shown - expected).max() <= 1.0 / 255


def test_an_sdf_pass_runs_in_webgl2_as_on_shadertoy(tmp_path):
    """An SDF pass in a browser's WebGL2, against inshade render away from edges."""
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import load_scene, resolve_asset
    from inshade.web.browser import psnr8, srgb8
    from inshade.web.shadertoy import PSNR_RULE, SDF_CHECK_SIZE, sdf_pass, stable_pixels

    n = SDF_CHECK_SIZE
    scene = load_scene(resolve_asset("sdf_occlusion"))
    shown = _in_chromium(sdf_pass(resolve_asset("sdf_occlusion")), n, n, tmp_path)[::-1]
    image8 = srgb8(render_scene(scene, width=n, height=n, settings={"labels": False})[0])
    stable = stable_pixels(scene, image8, n)
    assert psnr8(shown[stable], image8[stable]) >= PSNR_RULE


def test_compact_keeps_what_is_reached_and_drops_the_rest():
    from inshade.shaders.compact import compact

    source = """// a comment
#define N 2
const float K = 2.0;   // kept: a declaration
float used(float x) { return helper(x) * K; }
vec4 used(vec4 x) {
    return x;
}
float helper(float x) { return x; }   /* called by used */
float unused(float x) {
    return used(x);
}

void mainImage(out vec4 c, in vec2 p) { c = used(vec4(p, 0.0, N)); }
"""
    out = compact(source, roots=("mainImage",))
    assert "unused" not in out and "//" not in out and "/*" not in out and "\n\n" not in out
    for kept in ("#define N 2", "const float K = 2.0;", "float used(float x)", "vec4 used(vec4 x) {",
                 "float helper(float x)", "void mainImage"):
        assert kept in out, kept


@pytest.mark.parametrize("asset", ["sdf_creature", "sdf_occlusion"])
def test_an_sdf_pass_draws_what_inshade_render_draws(gl, asset):
    """An SDF scene as a pass: sphere traced from the scene's orbit camera, as Shadertoy runs it, against
    inshade render (8-bit sRGB) away from edges; the picture upside down fails the same check."""
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import load_scene, resolve_asset
    from inshade.web.browser import psnr8, srgb8
    from inshade.web.shadertoy import SDF_CHECK_SIZE, check_sdf_pass, sdf_pass, stable_pixels

    p = sdf_pass(resolve_asset(asset))
    assert "void mainImage" in p.text and "#include" not in p.text and "#version" not in p.text
    result = check_sdf_pass(p, resolve_asset(asset), ctx=gl)
    assert result.ok and result.stable > 0.9, result.lines()
    n = SDF_CHECK_SIZE
    scene = load_scene(resolve_asset(asset))
    image8 = srgb8(render_scene(scene, width=n, height=n, settings={"labels": False})[0])
    shown = np.clip(np.rint(_run(gl, p, n, n, network=False)[:, :, :3] * 255), 0, 255).astype(np.uint8)
    stable = stable_pixels(scene, image8, n)
    assert psnr8(shown[stable], image8[stable]) < 30   # data orientation, not flipped: far off


def test_an_sdf_reading_textures_is_refused():
    from inshade.scene.description import resolve_asset
    from inshade.web.shadertoy import sdf_pass

    with pytest.raises(TargetError, match=r"^shadertoy: hash_grid_sdf's SDF network reads \d+ textures"):
        sdf_pass(resolve_asset("hash_grid_sdf"))
