"""The headless GL runtime on the real driver: context, program errors, passes, read-back, files."""

import json

import numpy as np
import pytest

from inshade.shaders import LIBRARY_DIR, ShaderCompileError, ShaderIncludeError
from inshade.runtime.context import create_context, egl_devices, gl_info, shared_context
from inshade.scene.image_io import read_exr, write_exr, write_png, write_sidecar
from inshade.runtime.programs import ProgramCache
from inshade.runtime.render import (
    FullscreenPass,
    MeshPass,
    float_target,
    read_rgba,
    read_rgba_raw,
    upload_float_texture,
)

UV_FRAG = "in vec2 v_uv;\nout vec4 frag_color;\nvoid main() { frag_color = vec4(v_uv, 0.0, 1.0); }\n"


@pytest.fixture
def programs(gl, tmp_path):
    return ProgramCache(gl, dump_dir=tmp_path / "dump")


def test_context_reports_driver(gl):
    info = gl_info(gl)
    assert info["renderer"] and info["vendor"] and info["version"]
    assert info["glsl_version"][0].isdigit()
    assert info["GL_MAX_DRAW_BUFFERS"] >= 4 and info["GL_MAX_UNIFORM_BLOCK_SIZE"] >= 16384
    assert isinstance(info["software"], bool)
    assert all(isinstance(device, str) for device in egl_devices())


def test_second_context_does_not_break_shared(gl):
    create_context()
    ctx = shared_context()
    fbo = float_target(ctx, 2, 2)
    fbo.clear(0.25, 0.5, 0.75, 1.0)
    assert np.all(read_rgba(fbo) == np.float32([0.25, 0.5, 0.75, 1.0]))


@pytest.mark.parametrize("version", ["330", "450"])
def test_compile_error_points_at_chunk_line(programs, tmp_path, version):
    """An error on line 4 of an included chunk is reported as that chunk and line.

    The included chunk has an error Mesa reports with source-string 0 (undeclared identifier),
    which is why line numbers encode the chunk (see shaders/library.py).
    """
    chunks = {
        "test/main.frag": "#include <lib/colour>\n#include <test/broken>\nout vec4 frag_color;\n"
                          "void main() { frag_color = vec4(broken()); }\n",
        "test/broken": "// a chunk with an error on line 4\nfloat broken() {\n    float ok = 1.0;\n"
                       "    return ok + undeclared_thing;\n}\n",
    }
    with pytest.raises(ShaderCompileError) as caught:
        programs.get("common/fullscreen.vert", "test/main.frag", version=version, chunks=chunks)
    error = caught.value
    assert (error.chunk, error.line) == ("test/broken", 4)
    assert "undeclared_thing" in error.message
    assert str(error).startswith("<test/broken>:4: error")
    assert error.source_path.parent == tmp_path / "dump" and error.source_path.name.endswith(".frag.glsl")
    assert "undeclared_thing" in error.source_path.read_text()


def test_syntax_error_in_library_file_chunk(programs):
    chunks = {"lib/colour": "vec3 srgb_oetf(vec3 x) {\n    return x\n}\n",
              "test/main.frag": "#include <lib/colour>\nout vec4 c;\nvoid main() { c = vec4(srgb_oetf(vec3(1)), 1); }"}
    with pytest.raises(ShaderCompileError) as caught:
        programs.get("common/fullscreen.vert", "test/main.frag", chunks=chunks)
    assert caught.value.chunk == "lib/colour" and caught.value.line == 3  # the parser fails at "}"


def test_vertex_stage_error_is_mapped(programs):
    chunks = {"test/bad.vert": "void main() {\n    gl_Position = vec4(nope);\n}\n"}
    with pytest.raises(ShaderCompileError) as caught:
        programs.get("test/bad.vert", "passes/copy.frag", chunks=chunks)
    assert (caught.value.chunk, caught.value.line) == ("test/bad.vert", 2)
    assert caught.value.source_path.name.endswith(".vert.glsl")


def test_link_error(programs):
    chunks = {"test/main.frag": "in vec3 v_uv;\nout vec4 c;\nvoid main() { c = vec4(v_uv, 1.0); }"}
    with pytest.raises(ShaderCompileError, match="^link: .*v_uv") as caught:
        programs.get("common/fullscreen.vert", "test/main.frag", chunks=chunks)
    assert caught.value.chunk is None and caught.value.source_path.is_file()


def test_include_errors_pass_through(programs):
    with pytest.raises(ShaderIncludeError):
        programs.get("common/fullscreen.vert", "test/main.frag", chunks={"test/main.frag": "#include <nope>"})


def test_program_cache_reuses_and_times(programs):
    first = programs.get("common/fullscreen.vert", "passes/copy.frag")
    seconds = programs.last_compile_seconds
    assert seconds > 0
    assert programs.get("common/fullscreen.vert", "passes/copy.frag") is first
    assert programs.last_compile_seconds == seconds
    assert programs.get("common/fullscreen.vert", "passes/copy.frag", defines={"X": 1}) is not first


@pytest.mark.parametrize("width, height", [(7, 5), (64, 48)])
def test_fullscreen_uv_matches_pixel_centres(gl, programs, width, height):
    program = programs.get("common/fullscreen.vert", "test/uv.frag", chunks={"test/uv.frag": UV_FRAG})
    fbo = float_target(gl, width, height)
    FullscreenPass(gl, program).render(fbo)
    x = (np.arange(width) + 0.5) / width
    y = (np.arange(height) + 0.5) / height
    raw = read_rgba_raw(fbo)
    np.testing.assert_allclose(raw[..., 0], np.broadcast_to(x, (height, width)), atol=1e-6, rtol=0)
    np.testing.assert_allclose(raw[..., 1], np.broadcast_to(y[:, None], (height, width)), atol=1e-6, rtol=0)
    assert np.all(raw[..., 3] == 1.0)
    image = read_rgba(fbo)  # image orientation: the top row has the largest v
    np.testing.assert_array_equal(image, raw[::-1])
    assert image[0, 0, 1] > image[-1, 0, 1]


def test_float_texture_copy_round_trips_exactly(gl, programs):
    rng = np.random.default_rng(1)
    data = rng.standard_normal((13, 17, 4)).astype(np.float32) * np.float32(1e3)
    data[0, 0] = [np.float32(1e-38), -0.0, np.finfo(np.float32).max, np.float32(np.pi)]
    program = programs.get("common/fullscreen.vert", "passes/copy.frag")
    fbo = float_target(gl, 17, 13)
    FullscreenPass(gl, program).render(fbo, textures={"u_source": upload_float_texture(gl, data)})
    np.testing.assert_array_equal(read_rgba_raw(fbo), data)


def test_texel_fetch_convention(gl, programs):
    """texel (x, y) == array[y, x] and pixel (x, y) == read_rgba_raw(...)[y, x]: no flips for data."""
    data = np.arange(3 * 5, dtype=np.float32).reshape(3, 5)
    frag = ("uniform sampler2D u_data;\nout vec4 frag_color;\n"
            "void main() { ivec2 p = ivec2(gl_FragCoord.xy);\n"
            "    frag_color = vec4(texelFetch(u_data, p, 0).r, vec2(p), 1.0); }\n")
    program = programs.get("common/fullscreen.vert", "test/fetch.frag", chunks={"test/fetch.frag": frag})
    fbo = float_target(gl, 5, 3)
    FullscreenPass(gl, program).render(fbo, textures={"u_data": upload_float_texture(gl, data)})
    out = read_rgba_raw(fbo)
    np.testing.assert_array_equal(out[..., 0], data)
    ys, xs = np.mgrid[0:3, 0:5]
    np.testing.assert_array_equal(out[..., 1], xs)
    np.testing.assert_array_equal(out[..., 2], ys)


def test_mrt_targets(gl, programs):
    frag = ("layout(location = 0) out vec4 a;\nlayout(location = 1) out vec4 b;\n"
            "void main() { a = vec4(1.0, 2.0, 3.0, 4.0); b = vec4(-1.0); }\n")
    program = programs.get("common/fullscreen.vert", "test/mrt.frag", chunks={"test/mrt.frag": frag})
    fbo = float_target(gl, 3, 2, attachments=2)
    FullscreenPass(gl, program).render(fbo)
    assert np.all(read_rgba_raw(fbo, 0) == np.float32([1, 2, 3, 4]))
    assert np.all(read_rgba_raw(fbo, 1) == -1.0)
    with pytest.raises(ValueError):
        float_target(gl, 2, 2, attachments=gl.info["GL_MAX_DRAW_BUFFERS"] + 1)


def test_mesh_pass_depth_and_camera(gl, programs):
    """The near quad (z = -1, centre of the view) is drawn first; the far one (z = -2) covers the
    whole view but must lose the depth test in the centre."""
    frag = "in vec2 v_uv;\nin vec3 v_world_position;\nout vec4 c;\nvoid main() { c = vec4(v_world_position, 1.0); }\n"
    program = programs.get("common/mesh.vert", "test/pos.frag", chunks={"test/pos.frag": frag})
    quad = np.float32([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
    near, far = quad * [0.5, 0.5, 1] + [0, 0, -1], quad * [4, 4, 1] + [0, 0, -2]
    vertices = np.concatenate([near, far])
    normals = np.tile(np.float32([0, 0, 1]), (8, 1))
    uvs = np.tile(np.float32([[0, 0], [1, 0], [1, 1], [0, 1]]), (2, 1))
    indices = np.int32([0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7])
    n, f = 0.1, 10.0
    proj = np.float32([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -(f + n) / (f - n), -2 * f * n / (f - n)], [0, 0, -1, 0]])
    eye = np.eye(4, dtype=np.float32)
    fbo = float_target(gl, 16, 16, depth=True)
    fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
    mesh = MeshPass(gl, program, vertices, normals, uvs, indices)
    # GLSL mat4 is column-major: pass the transpose of a row-major numpy matrix.
    mesh.render(fbo, uniforms={"u_model": eye.T.tobytes(), "u_view": eye.T.tobytes(), "u_proj": proj.T.tobytes()})
    image = read_rgba(fbo)
    assert image[8, 8, 2] == pytest.approx(-1.0) and image[8, 8, 3] == 1.0
    assert image[0, 0, 2] == pytest.approx(-2.0)


def test_png_exr_and_sidecar(tmp_path, gl):
    rng = np.random.default_rng(2)
    linear = (rng.random((6, 9, 4)) * 4).astype(np.float32)
    exr = write_exr(tmp_path / "render.exr", linear)
    np.testing.assert_array_equal(read_exr(exr), linear)
    np.testing.assert_array_equal(read_exr(write_exr(tmp_path / "rgb.exr", linear[..., :3])), linear[..., :3])

    from PIL import Image

    ramp = np.zeros((2, 3, 3), np.float32)
    ramp[0] = [[0.0] * 3, [0.5] * 3, [1.0] * 3]  # top row
    ramp[1] = [[0.0031308] * 3, [2.0] * 3, [-1.0] * 3]
    png = np.asarray(Image.open(write_png(tmp_path / "ramp.png", ramp)))
    assert png.shape == (2, 3, 3)
    assert png[0, :, 0].tolist() == [0, 188, 255]  # sRGB(0.5) = 0.7354 -> 188
    assert png[1, :, 0].tolist() == [10, 255, 0]
    reinhard = np.asarray(Image.open(write_png(tmp_path / "r.png", np.full((1, 1, 3), 1.0), tonemap="reinhard")))
    assert reinhard[0, 0, 0] == 188  # 1 / (1 + 1) = 0.5
    half = np.asarray(Image.open(write_png(tmp_path / "e.png", np.full((1, 1, 3), 0.25), exposure=2.0)))
    assert half[0, 0, 0] == 188
    with pytest.raises(ValueError):
        write_png(tmp_path / "x.png", ramp, tonemap="aces")

    renderer = gl_info(gl)["renderer"]
    sidecar = write_sidecar(exr, {"renderer": renderer, "camera": np.eye(4), "spp": np.int64(1)})
    assert sidecar.name == "render.exr.json"
    record = json.loads(sidecar.read_text())
    assert record["renderer"] == renderer and record["camera"][0] == [1.0, 0.0, 0.0, 0.0] and record["spp"] == 1
    assert record["inshade_version"] and record["timestamp_utc"].endswith("+00:00")


def test_library_dir_is_the_package():
    assert (LIBRARY_DIR / "common" / "fullscreen.vert.glsl").is_file()
