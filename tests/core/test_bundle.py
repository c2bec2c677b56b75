"""Bundle loading: every malformed file gives exactly one BundleError naming the file and the
field; save/load round trip; digest stability; no pickle anywhere."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors.numpy import load_file, save_file

from inshade.bundle import JSON_NAME, WEIGHTS_NAME, Bundle, BundleError, canonical_json, load
from inshade.components.dense.torch_twin import Dense
from inshade.components.elementwise.torch_twin import ReLU
from inshade.components.lookup_array.torch_twin import LookupArray
from inshade.models import GraphModule

REPO = Path(__file__).resolve().parents[2]


def sample_graph() -> GraphModule:
    torch.manual_seed(0)
    g = GraphModule([("uv", 2)])
    g.add("lut", LookupArray([4, 3], 5, bits=8, nonlinearity="triangle",
                             init=torch.rand(3, 4, 5) * 3), "uv")
    g.add("l0", Dense(5, 6), "lut")
    g.add("a0", ReLU(), "l0")
    g.add("l1", Dense(6, 3), "a0")
    g.output("rgb", "l1")
    return g


@pytest.fixture
def bundle_dir(tmp_path) -> Path:
    return sample_graph().export("sample").save(tmp_path / "b")


def _meta(folder):
    return json.loads((folder / JSON_NAME).read_text())


def _write_meta(folder, meta):
    (folder / JSON_NAME).write_text(json.dumps(meta))


def _tensors(folder):
    return load_file(str(folder / WEIGHTS_NAME))


def _write_tensors(folder, tensors):
    save_file(tensors, str(folder / WEIGHTS_NAME))


def _expect(folder, file: str, field: str, message: str = "") -> BundleError:
    """Exactly one BundleError (no chained exception) naming `file` and `field`."""
    with pytest.raises(BundleError) as info:
        load(folder)
    e = info.value
    assert type(e) is BundleError
    assert e.__cause__ is None and (e.__context__ is None or e.__suppress_context__), "chained error"
    assert Path(e.where).name == file, str(e)
    assert e.field == field, str(e)
    assert re.search(message, e.message), str(e)
    assert file in str(e) and field in str(e)
    return e


# --- weights.safetensors -------------------------------------------------------------------

def test_truncated_safetensors(bundle_dir):
    data = (bundle_dir / WEIGHTS_NAME).read_bytes()
    (bundle_dir / WEIGHTS_NAME).write_bytes(data[: len(data) // 2])
    _expect(bundle_dir, WEIGHTS_NAME, "", "truncated|unreadable")


def test_truncated_header(bundle_dir):
    (bundle_dir / WEIGHTS_NAME).write_bytes(b"\x10\x00")
    _expect(bundle_dir, WEIGHTS_NAME, "", "truncated")


def test_garbage_safetensors(bundle_dir):
    (bundle_dir / WEIGHTS_NAME).write_bytes((20).to_bytes(8, "little") + b"{not json at all....")
    _expect(bundle_dir, WEIGHTS_NAME, "", "unreadable")


def test_missing_weights_file(bundle_dir):
    (bundle_dir / WEIGHTS_NAME).unlink()
    _expect(bundle_dir, WEIGHTS_NAME, "", "missing")


def test_missing_tensor(bundle_dir):
    t = _tensors(bundle_dir)
    del t["l0.bias"]
    _write_tensors(bundle_dir, t)
    _expect(bundle_dir, WEIGHTS_NAME, "l0.bias", "missing tensor")


def test_extra_tensor(bundle_dir):
    t = _tensors(bundle_dir)
    t["l9.weight"] = np.zeros((2, 2), np.float32)
    _write_tensors(bundle_dir, t)
    _expect(bundle_dir, WEIGHTS_NAME, "l9.weight", "unexpected tensor")


def test_wrong_shape(bundle_dir):
    t = _tensors(bundle_dir)
    t["l1.weight"] = t["l1.weight"].T.copy()
    _write_tensors(bundle_dir, t)
    _expect(bundle_dir, WEIGHTS_NAME, "l1.weight", r"shape \[6, 3\] but \[3, 6\]")


@pytest.mark.parametrize("name,dtype", [("l0.weight", np.float64), ("l0.bias", np.int32),
                                         ("lut.cells", np.uint16), ("lut.scale", np.float64),
                                         ("lut.cells", np.float16)])
def test_wrong_dtype(bundle_dir, name, dtype):
    t = _tensors(bundle_dir)
    t[name] = t[name].astype(dtype)
    _write_tensors(bundle_dir, t)
    _expect(bundle_dir, WEIGHTS_NAME, name, "dtype")


def test_half_weights_widened_to_float32(bundle_dir):
    """float16 weights load as float32 (exact), and the bundle records which were widened."""
    t = _tensors(bundle_dir)
    t["l0.weight"] = t["l0.weight"].astype(np.float16)
    _write_tensors(bundle_dir, t)
    b = load(bundle_dir)
    assert b.converted == {"l0.weight": "float16"}
    assert b.tensors["l0.weight"].dtype == np.float32
    np.testing.assert_array_equal(b.tensors["l0.weight"], t["l0.weight"].astype(np.float32))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("name", ["l0.weight", "l1.bias", "lut.offset"])
def test_non_finite(bundle_dir, name, bad):
    t = _tensors(bundle_dir)
    t[name].reshape(-1)[0] = bad
    _write_tensors(bundle_dir, t)
    _expect(bundle_dir, WEIGHTS_NAME, name, "NaN or Inf")


# --- bundle.json ---------------------------------------------------------------------------

def _node_index(meta, node_id):
    return next(i for i, n in enumerate(meta["nodes"]) if n["id"] == node_id)


def test_unknown_component_type(bundle_dir):
    meta = _meta(bundle_dir)
    meta["nodes"][_node_index(meta, "a0")]["type"] = "conv2d"
    _write_meta(bundle_dir, meta)
    _expect(bundle_dir, JSON_NAME, "nodes[2].type", "unknown component type: conv2d")


@pytest.mark.parametrize("version,message", [(2, "unsupported version 2"), (0, "unsupported"),
                                             ("1", "must be int"), (True, "must be int"), (1.0, "must be int")])
def test_wrong_version(bundle_dir, version, message):
    meta = _meta(bundle_dir)
    meta["version"] = version
    _write_meta(bundle_dir, meta)
    _expect(bundle_dir, JSON_NAME, "version", message)


def test_missing_version(bundle_dir):
    meta = _meta(bundle_dir)
    del meta["version"]
    _write_meta(bundle_dir, meta)
    _expect(bundle_dir, JSON_NAME, "version", "missing")


@pytest.mark.parametrize("fmt", ["inshade.bundle2", "safetensors", ""])
def test_wrong_format_string(bundle_dir, fmt):
    meta = _meta(bundle_dir)
    meta["format"] = fmt
    _write_meta(bundle_dir, meta)
    _expect(bundle_dir, JSON_NAME, "format", "expected 'inshade.bundle'")


def test_absurd_dense_width(bundle_dir):
    meta = _meta(bundle_dir)
    meta["nodes"][_node_index(meta, "l0")]["params"]["out"] = 10**9
    _write_meta(bundle_dir, meta)
    _expect(bundle_dir, JSON_NAME, "nodes[1].params", "invalid value")


@pytest.mark.parametrize("resolution,message", [([65536, 65536], "absurdly large"),
                                                ([1 << 17, 2], "resolution"), ([0, 3], "resolution"),
                                                ([4, 3, 2], "needs a 3-wide input")])
def test_absurd_lookup_array(bundle_dir, resolution, message):
    meta = _meta(bundle_dir)
    meta["nodes"][_node_index(meta, "lut")]["params"]["resolution"] = resolution
    _write_meta(bundle_dir, meta)
    _expect(bundle_dir, JSON_NAME, "nodes[0].params", message)


def test_absurd_input_dim(bundle_dir):
    meta = _meta(bundle_dir)
    meta["inputs"][0]["dim"] = 10**6
    _write_meta(bundle_dir, meta)
    _expect(bundle_dir, JSON_NAME, "inputs[0].dim", "must be 1..")


def test_dangling_node_input(bundle_dir):
    meta = _meta(bundle_dir)
    meta["nodes"][_node_index(meta, "l1")]["inputs"] = ["a7"]
    _write_meta(bundle_dir, meta)
    _expect(bundle_dir, JSON_NAME, "nodes[3].inputs", "'a7' is not an input or an earlier node")


def test_forward_reference_is_dangling(bundle_dir):
    meta = _meta(bundle_dir)
    meta["nodes"][_node_index(meta, "l0")]["inputs"] = ["a0"]  # defined later
    _write_meta(bundle_dir, meta)
    _expect(bundle_dir, JSON_NAME, "nodes[1].inputs", "'a0' is not")


def test_dangling_output(bundle_dir):
    meta = _meta(bundle_dir)
    meta["outputs"][0]["node"] = "nowhere"
    _write_meta(bundle_dir, meta)
    _expect(bundle_dir, JSON_NAME, "outputs[0].node", "not a node")


def test_two_outputs_of_one_name(bundle_dir, capsys):
    """load, and so info / codegen / render, refuse it: outputs are found by name."""
    from inshade.cli import main

    meta = _meta(bundle_dir)
    meta["outputs"].append(dict(meta["outputs"][0]))
    _write_meta(bundle_dir, meta)
    _expect(bundle_dir, JSON_NAME, "outputs[1].name", "invalid or repeated name")
    for argv in (["info", str(bundle_dir)], ["codegen", str(bundle_dir), "--no-gl"]):
        assert main(argv) == 2
        assert len(capsys.readouterr().err.strip().splitlines()) == 1


@pytest.mark.parametrize("dup", ["l0", "uv"])
def test_duplicate_ids(bundle_dir, dup):
    meta = _meta(bundle_dir)
    meta["nodes"][_node_index(meta, "a0")]["id"] = dup
    _write_meta(bundle_dir, meta)
    _expect(bundle_dir, JSON_NAME, "nodes[2].id", "repeated")


@pytest.mark.parametrize("text", ['{"format": "inshade.bundle", ', "", "[1, 2", "\xff\xfe"])
def test_invalid_json(bundle_dir, text):
    (bundle_dir / JSON_NAME).write_bytes(text.encode("latin-1"))
    _expect(bundle_dir, JSON_NAME, "", "not valid JSON")


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity"])
def test_json_nan_literal(bundle_dir, literal):
    text = (bundle_dir / JSON_NAME).read_text()
    text = text.replace('"metrics": {}', f'"metrics": {{"psnr": {literal}}}')
    assert literal in text
    (bundle_dir / JSON_NAME).write_text(text)
    _expect(bundle_dir, JSON_NAME, "", "not valid JSON")


def test_top_level_not_object(bundle_dir):
    (bundle_dir / JSON_NAME).write_text("[]")
    _expect(bundle_dir, JSON_NAME, "", "object")


def test_unknown_top_level_field(bundle_dir):
    meta = _meta(bundle_dir)
    meta["weights"] = "evil.pkl"
    _write_meta(bundle_dir, meta)
    _expect(bundle_dir, JSON_NAME, "weights", "unknown top-level field")


def test_unknown_param(bundle_dir):
    meta = _meta(bundle_dir)
    meta["nodes"][_node_index(meta, "l0")]["params"]["activation"] = "relu"
    _write_meta(bundle_dir, meta)
    _expect(bundle_dir, JSON_NAME, "nodes[1].params", "unknown params")


def test_not_a_folder(tmp_path):
    with pytest.raises(BundleError, match="not a bundle folder"):
        load(tmp_path / "nope")


# --- round trip, digest, no pickle ------------------------------------------------------------

def test_save_load_round_trip(tmp_path):
    g = sample_graph()
    b = g.export("sample", provenance={"cmd": "train --x"}, metrics={"psnr": 31.5})
    loaded = load(b.save(tmp_path / "b"))
    assert loaded.meta == b.meta
    assert sorted(loaded.tensors) == sorted(b.tensors)
    for k in b.tensors:
        assert loaded.tensors[k].dtype == b.tensors[k].dtype
        np.testing.assert_array_equal(loaded.tensors[k], b.tensors[k])
    assert loaded.digest() == b.digest()
    x = torch.rand(50, 2)
    with torch.no_grad():
        np.testing.assert_array_equal(GraphModule.from_bundle(loaded)(x).numpy(),
                                      GraphModule.from_bundle(b)(x).numpy())
    # saving what was loaded reproduces the files byte for byte
    folder2 = loaded.save(tmp_path / "c")
    for name in (JSON_NAME, WEIGHTS_NAME):
        assert (tmp_path / "b" / name).read_bytes() == (folder2 / name).read_bytes()
    assert (folder2 / JSON_NAME).read_text() == canonical_json(b.meta)


def test_digest_stability():
    """The digest is a function of canonical JSON + tensors only: insertion order does not
    matter, any change to a value does, and a fixed bundle has a fixed digest."""
    meta = {"format": "inshade.bundle", "version": 1, "kind": "k",
            "inputs": [{"name": "x", "dim": 2}],
            "nodes": [{"id": "l0", "type": "dense", "inputs": ["x"], "params": {"out": 1}}],
            "outputs": [{"name": "y", "node": "l0"}]}
    w = np.array([[0.5, -0.25]], np.float32)
    b = np.array([0.125], np.float32)
    d1 = Bundle(meta, {"l0.weight": w, "l0.bias": b}).digest()
    d2 = Bundle(json.loads(json.dumps(meta, sort_keys=True)), {"l0.bias": b, "l0.weight": w}).digest()
    assert d1 == d2
    assert Bundle(meta, {"l0.weight": w, "l0.bias": b + 1}).digest() != d1
    # recorded when the v1 format was frozen: a change here means old renders lose their name
    assert d1 == "13b7bf80ebb5b2831c5fa5ecf15866900814eee05af7a4dc03ddfece5a1da285"


def test_exported_digest_is_reproducible():
    assert sample_graph().export("sample").digest() == sample_graph().export("sample").digest()


def test_no_pickle_anywhere():
    """A bundle from a stranger must not be able to run code: no pickle, torch.load or
    np.load(allow_pickle) in the package. The one exception is torch.load with weights_only=True
    (tensors only: a tiny-cuda-nn model's saved params), and catching the UnpicklingError it raises
    for anything else."""
    pattern = re.compile(r"\bpickle\b|torch\.load\b|allow_pickle\s*=\s*True|\bdill\b|joblib")
    safe = re.compile(r"weights_only=True|UnpicklingError")
    offenders = []
    for folder in ("inshade", "models", "codegen", "viewer", "shaders"):
        for path in sorted((REPO / folder).rglob("*.py")):
            text = path.read_text()
            catches = "UnpicklingError" in text
            for number, line in enumerate(text.splitlines(), 1):
                if line.strip() == "import pickle" and catches:
                    continue
                if pattern.search(line) and not safe.search(line):
                    offenders.append(f"{path.relative_to(REPO)}:{number}: {line.strip()}")
    assert not offenders, "\n".join(offenders)
