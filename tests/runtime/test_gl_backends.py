"""The two headless GL backends (EGL, OSMesa), EGL device selection and `inshade doctor`.

Parity between backends: a few generated networks (one per weight placement) and two shipped
assets are rendered under EGL and under OSMesa, each in a fresh process (PyOpenGL picks its
platform once per process, and the run itself may use either). Tolerance: bit-identical whenever both report
the same GL_RENDERER. Here both are Mesa's llvmpipe from one Mesa build (libEGL_mesa and
libOSMesa), which JIT-compiles the same shader code; only the window-system layer differs, and
inshade draws into its own float FBOs, so nothing in the pixels depends on it. With different
renderers (EGL on a GPU) only the network outputs are compared, each against torch under
tests/parity.py's rule, which holds on any driver.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from inshade.cli import _split_gl_options, main
from inshade.runtime import context
from inshade.runtime.context import BACKEND_ENV, DEVICE_ENV, EGLDevice, GLContextError

from parity import MLPSpec, assert_parity, build_mlp, glsl_eval, spec_inputs, torch_reference
from shipped_renders import key, render_case

N = 64
# (name, spec, storage): one per weight placement, odd widths (padding), several output blocks
NETWORKS = [
    ("relu_inline", MLPSpec([2], [16, 13], [("relu", {})] * 2, 3, ("sigmoid", {}), None, [True] * 3, seed=1),
     "inline"),
    ("siren_ubo", MLPSpec([3], [12, 8], [("sin", {"omega0": 30.0}), ("tanh", {})], 4, None, 0, [True] * 3, seed=2),
     "ubo"),
    ("wide_texture", MLPSpec([3, 2], [64, 32], [("softplus", {}), ("leaky_relu", {"slope": 0.1})], 9, None, None,
                             [True, False, True], seed=3), "texture"),
]
ASSETS = [("neural_image", {}), ("di_pbr_set_bricks", {})]


def render_set() -> dict[str, np.ndarray]:
    """Network outputs and asset renders on the shared context of this process's backend."""
    from inshade.runtime.context import gl_info, shared_context

    ctx = shared_context()
    out = {"backend": np.array(ctx.extra["backend"]), "renderer": np.array(gl_info(ctx)["renderer"])}
    for name, spec, storage in NETWORKS:
        out[f"net_{name}"] = glsl_eval(ctx, build_mlp(spec).export("mlp"), spec_inputs(spec, N), storage=storage)
    for asset, settings in ASSETS:
        out[f"asset_{key(asset, settings)}"] = render_case(asset, settings)
    return out


def _fresh_env(**extra) -> dict:
    """This process's environment without its GL choices (a run under --gl-backend osmesa exports
    them), plus ``extra``: a subprocess chooses its backend as a user's shell would."""
    env = {k: v for k, v in os.environ.items() if k not in (BACKEND_ENV, DEVICE_ENV, "PYOPENGL_PLATFORM")}
    return {**env, "OMP_NUM_THREADS": "1", **extra}


def _cli(*args, env=None, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "inshade.cli", *args], capture_output=True, text=True,
                          env=_fresh_env(**(env or {})), **kw)


def _one_error_line(stderr: str) -> str:
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("inshade: error: "), stderr
    assert "Traceback" not in stderr
    return lines[0]


@pytest.fixture(autouse=True)
def gl_env(monkeypatch):
    """No backend/device choice from outside; what select() writes is undone after the test."""
    for name in (BACKEND_ENV, DEVICE_ENV):
        monkeypatch.setenv(name, "")   # recorded first, so the undo removes it again
        monkeypatch.delenv(name)


# --- parity between backends -----------------------------------------------------------------

def _render_set_in(backend: str, tmp_path_factory) -> dict:
    """The parity set rendered by a fresh process on ``backend`` (each backend is chosen once per process)."""
    out = tmp_path_factory.mktemp(backend) / "set.npz"
    tests = str(Path(__file__).resolve().parents[1])     # the shared helpers (parity.py, shipped_renders.py)
    path = os.pathsep.join(filter(None, [tests, os.environ.get("PYTHONPATH")]))
    r = subprocess.run([sys.executable, __file__, str(out)], capture_output=True, text=True,
                       env=_fresh_env(**{BACKEND_ENV: backend, "PYTHONPATH": path}))
    assert r.returncode == 0, r.stderr
    with np.load(out) as data:
        return {k: data[k] for k in data.files}


@pytest.fixture(scope="module")
def osmesa_set(tmp_path_factory):
    return _render_set_in("osmesa", tmp_path_factory)


@pytest.fixture(scope="module")
def egl_set(tmp_path_factory):
    return _render_set_in("egl", tmp_path_factory)


def test_osmesa_subprocess_really_used_osmesa(osmesa_set, egl_set):
    assert str(osmesa_set["backend"]) == "osmesa" and str(egl_set["backend"]) == "egl"
    assert str(osmesa_set["renderer"])


@pytest.mark.parametrize("name,spec,storage", NETWORKS, ids=[n for n, _, _ in NETWORKS])
def test_networks_match_across_backends(osmesa_set, egl_set, name, spec, storage):
    ref = torch_reference(build_mlp(spec).export("mlp"), spec_inputs(spec, N))
    for backend, images in (("egl", egl_set), ("osmesa", osmesa_set)):
        assert_parity(images[f"net_{name}"], ref, what=f"{name} ({storage}) on {backend}")
    if str(osmesa_set["renderer"]) == str(egl_set["renderer"]):
        assert np.array_equal(osmesa_set[f"net_{name}"], egl_set[f"net_{name}"])


@pytest.mark.parametrize("asset,settings", ASSETS, ids=[key(a, s) for a, s in ASSETS])
def test_shipped_asset_matches_across_backends(osmesa_set, egl_set, asset, settings):
    a, b = osmesa_set[f"asset_{key(asset, settings)}"], egl_set[f"asset_{key(asset, settings)}"]
    assert a.shape == b.shape and float(np.abs(b).max()) > 0
    if str(osmesa_set["renderer"]) == str(egl_set["renderer"]):
        diff = np.abs(a.astype(np.float64) - b)
        assert np.array_equal(a, b), f"{int((diff > 0).sum())} values differ, max {diff.max():.3g}"


# --- option and variable spellings -------------------------------------------------------------

@pytest.mark.parametrize("argv", [
    ["-q", "--gl-backend", "egl", "--gl-device", "0", "doctor", "--json"],
    ["-q", "doctor", "--json", "--gl-device=0", "--gl-backend=egl"],
])
def test_gl_flags_select_backend_and_device(capsys, argv):
    assert main(argv) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["gl_backend"] == "egl" and info["egl_device"] == 0
    assert os.environ[BACKEND_ENV] == "egl" and os.environ[DEVICE_ENV] == "0"   # for worker processes


def test_gl_env_variables_are_read(monkeypatch, capsys):
    monkeypatch.setenv(BACKEND_ENV, "egl")
    monkeypatch.setenv(DEVICE_ENV, "0")
    assert context.resolve() == ("egl", 0)
    assert main(["-q", "doctor", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["egl_device"] == 0
    monkeypatch.setenv(BACKEND_ENV, "osmesa")   # an environment-wide device does not concern OSMesa
    assert context.resolve() == ("osmesa", None)
    assert context.resolve("egl", 0) == ("egl", 0)   # flags win over the environment


def test_osmesa_flag_from_the_command_line():
    r = _cli("-q", "--gl-backend", "osmesa", "doctor", "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["gl_backend"] == "osmesa" and info["egl_device"] is None
    assert info["version"].startswith(("3.3", "4.")) and info["renderer"]


def test_bench_and_train_take_gl_options_among_their_own():
    assert _split_gl_options(["--size", "8", "--gl-device", "1", "--gl-backend=egl", "--", "--gl-device", "2"]) == \
        (["--gl-device", "1", "--gl-backend=egl"], ["--size", "8", "--", "--gl-device", "2"])
    with pytest.raises(SystemExit) as exc:   # the module's --help: it never saw --gl-device
        main(["bench", "mlp", "--gl-device", "0", "--help"])
    assert exc.value.code == 0


# --- bad input: one error line, exit 2 ---------------------------------------------------------

def _count_devices() -> int:
    return len(context.egl_device_list())


@pytest.mark.parametrize("argv,env,says", [
    (["--gl-backend", "vulkan", "doctor"], {}, "invalid choice: 'vulkan'"),
    (["doctor", "--gl-device", "-1"], {}, "expected an EGL device index"),
    (["--gl-device", "99", "doctor"], {}, "EGL device 99 requested, but this machine has {n} EGL device"),
    (["bench", "mlp", "--gl-device", "99"], {}, "EGL device 99 requested"),
    (["--gl-backend", "osmesa", "--gl-device", "0", "doctor"], {}, "the osmesa backend renders on the CPU"),
    (["--gl-device", "0", "view"], {}, "a window renders on its display's GPU"),
    (["doctor"], {BACKEND_ENV: "vulkan"}, "INSHADE_GL_BACKEND: unknown GL backend 'vulkan'"),
    (["doctor"], {DEVICE_ENV: "99"}, "INSHADE_EGL_DEVICE: EGL device 99 requested"),
    (["doctor"], {DEVICE_ENV: "first"}, "INSHADE_EGL_DEVICE: expected an EGL device index"),
])
def test_bad_gl_choice_is_one_error_line(capsys, monkeypatch, argv, env, says):
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    try:
        rc = main(["-q", *argv])
    except SystemExit as exc:   # argparse's own errors
        rc = exc.code
    err = capsys.readouterr().err
    assert rc == 2
    assert says.format(n=_count_devices()) in _one_error_line(err)


def test_render_with_bad_env_backend(monkeypatch, tmp_path, capsys):
    monkeypatch.setenv(BACKEND_ENV, "vulkan")
    assert main(["-q", "render", "neural_image", "--width", "8", "--height", "8", "-o", str(tmp_path / "x.png")]) == 2
    assert "unknown GL backend" in _one_error_line(capsys.readouterr().err)


def test_osmesa_after_pyopengl_chose_another_platform():
    code = ("import sys, OpenGL.GL; from inshade.cli import main; "
            "sys.exit(main(['-q', '--gl-backend', 'osmesa', 'doctor']))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=_fresh_env())
    assert r.returncode == 2
    assert "PyOpenGL picks its platform once" in _one_error_line(r.stderr)
    r = _cli("-q", "--gl-backend", "osmesa", "doctor", env={"PYOPENGL_PLATFORM": "egl"})
    assert r.returncode == 2
    assert "PYOPENGL_PLATFORM=egl" in _one_error_line(r.stderr)


# --- doctor ---------------------------------------------------------------------------------

def test_doctor_lists_devices_and_marks_the_one_used(monkeypatch, capsys):
    devices = [EGLDevice(0, None, "EGL_MESA_device_software EGL_EXT_device_drm_render_node"),
               EGLDevice(1, "/dev/dri/card1", "EGL_NV_device_cuda EGL_EXT_device_drm")]
    monkeypatch.setattr(context, "egl_device_list", lambda: devices)
    assert main(["-q", "doctor"]) == 0
    out = capsys.readouterr().out
    assert "renderer" in out and "GL_MAX_UNIFORM_BLOCK_SIZE" in out   # the report it always gave
    assert "* 0: (no DRM node) EGL_MESA_device_software" in out and "[software]" in out
    assert "  1: /dev/dri/card1" in out and "* 1:" not in out
    assert "EGL sees no GPU" not in out


@pytest.mark.parametrize("devices", [[], [EGLDevice(0, None, "EGL_MESA_device_software")]])
def test_doctor_hint_when_egl_sees_no_gpu(monkeypatch, capsys, devices):
    monkeypatch.setattr(context, "egl_device_list", lambda: devices)
    assert main(["-q", "doctor"]) == 0
    out = capsys.readouterr().out
    assert f"EGL devices ({len(devices)};" in out
    assert "EGL sees no GPU" in out and "NVIDIA_DRIVER_CAPABILITIES=graphics" in out and "glvnd" in out


def test_doctor_suggests_osmesa_when_egl_cannot_start(monkeypatch, capsys):
    def no_egl():
        raise GLContextError("no headless OpenGL 3.3 context (egl: eglInitialize failed (0x3001))")

    monkeypatch.setattr(context, "shared_context", no_egl)
    assert main(["-q", "doctor"]) == 2
    captured = capsys.readouterr()
    assert "EGL devices (" in captured.out and "--gl-backend osmesa" in captured.out
    assert "0x3001" in _one_error_line(captured.err)


def test_nvidia_hints_name_the_missing_pieces(monkeypatch, tmp_path):
    monkeypatch.setenv("__EGL_VENDOR_LIBRARY_DIRS", str(tmp_path))   # an empty vendor folder
    monkeypatch.delenv("__EGL_VENDOR_LIBRARY_FILENAMES", raising=False)
    hints = " ".join(context.nvidia_hints())
    assert "10_nvidia.json" in hints
    (tmp_path / "10_nvidia.json").write_text('{"ICD": {"library_path": "libEGL_nvidia.so.0"}}')
    assert "10_nvidia.json" not in " ".join(context.nvidia_hints())


if __name__ == "__main__":   # one backend's parity set, run by _render_set_in in a fresh process
    np.savez(sys.argv[1], **render_set())
