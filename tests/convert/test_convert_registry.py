"""The tables of op lowerings (inshade/convert/registry.py): a name registered twice is refused
with both places named, the registry loads neither torch nor onnx, and every entry of each table
is reachable from what its source format writes (an ATen op, an ONNX op type, a tiny-cuda-nn
otype in any case)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from inshade.convert.registry import (ONNX_OPS, TCNN_ENCODINGS, TORCH_OPS, DuplicateLowering, Registry,
                                      onnx_op, tcnn_encoding, torch_op)

ROOT = Path(__file__).resolve().parents[2]


def test_a_duplicate_name_is_refused_naming_both_places():
    table = Registry("test op")

    @table.register("Relu", "Sigmoid")
    def first(walk, node, f):
        return f

    line = first.__code__.co_firstlineno   # the decorator's line (where a decorated def starts)
    with pytest.raises(DuplicateLowering) as caught:
        table.register("Sigmoid")(lambda walk, node, f: f)
    message = str(caught.value)
    assert message.startswith("test op 'Sigmoid' is registered twice: at ")
    assert f"{__file__}:{line}" in message                       # the first place
    assert message.count(__file__) == 2                          # and the second
    assert table["Sigmoid"] is first and sorted(table) == ["Relu", "Sigmoid"]


def test_a_folded_table_refuses_another_spelling():
    table = Registry("encoding", fold=str.lower)
    table.add("OneBlob", object)
    with pytest.raises(DuplicateLowering, match="encoding 'ONEBLOB' is registered twice"):
        table.add("ONEBLOB", object)
    assert "oneblob" in table and table.names() == ["OneBlob"]


@pytest.mark.parametrize("decorator, name, home", [(torch_op, "relu", "inshade/convert/"), (onnx_op, "Relu", "inshade/convert/"),
                                                   (tcnn_encoding, "frequency", "inshade/convert/"),
                                                   (tcnn_encoding, "oneblob", "components/one_blob/")])
def test_the_built_in_tables_refuse_a_second_lowering(decorator, name, home):
    import inshade.convert.onnx_model  # noqa: F401 (fills the tables)
    import inshade.convert.tcnn  # noqa: F401
    import inshade.convert.torch_module  # noqa: F401

    table = {torch_op: TORCH_OPS, onnx_op: ONNX_OPS, tcnn_encoding: TCNN_ENCODINGS}[decorator]
    before = table[name]
    with pytest.raises(DuplicateLowering, match=f"{name!r} is registered twice: at .*{home}.*:[0-9]+ and at "
                                                f".*test_convert_registry.py:[0-9]+"):
        decorator(name)(lambda *args: None)
    assert table[name] is before


def test_the_registry_loads_nothing_heavy():
    code = ("import json, sys\nimport inshade.convert.registry\n"
            "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in ('torch', 'onnx', 'onnxruntime'))))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == []


def test_every_torch_entry_is_an_aten_op_the_walk_dispatches():
    torch = pytest.importorskip("torch")
    from inshade.convert.torch_module import HANDLERS, _op_name

    assert HANDLERS is TORCH_OPS and len(TORCH_OPS) > 100
    for name in TORCH_OPS:
        op = getattr(torch.ops.aten, name)
        overload = getattr(op, op.overloads()[0])
        assert _op_name(overload) == name
        entry = TORCH_OPS.entry(name)
        assert callable(entry.lower) and "inshade/convert/ops/torch_" in entry.where, (name, entry.where)


def test_every_onnx_entry_is_a_standard_op_type():
    defs = pytest.importorskip("onnx.defs")
    from inshade.convert.onnx_model import HANDLERS

    assert HANDLERS is ONNX_OPS and len(ONNX_OPS) > 50
    for name in ONNX_OPS:
        assert defs.has(name), name
        entry = ONNX_OPS.entry(name)
        assert callable(entry.lower) and "inshade/convert/ops/onnx_" in entry.where, (name, entry.where)


# a config each tiny-cuda-nn otype takes, and the input width it encodes
TCNN_CASES = {"composite": ({"nested": [{"otype": "Identity"}]}, 2), "densegrid": ({"n_levels": 2}, 2),
              "empty": ({}, 2), "frequency": ({}, 2), "grid": ({"n_levels": 2, "log2_hashmap_size": 8}, 3),
              "hashgrid": ({"n_levels": 2, "log2_hashmap_size": 8}, 2), "identity": ({}, 2), "nrc": ({}, 9),
              "oneblob": ({}, 2), "oneblobfrequency": ({}, 8), "sphericalharmonics": ({}, 3),
              "trianglewave": ({}, 2)}


def test_every_tcnn_encoding_is_reachable_by_its_otype_in_any_case():
    from inshade.convert.lowering import ConvertError
    from inshade.convert.tcnn_config import Context, parse_encoding

    assert sorted(TCNN_ENCODINGS) == sorted([*TCNN_CASES, "tiledgrid"])
    for otype, (cfg, n_dims) in TCNN_CASES.items():
        for spelling in (otype, otype.upper()):
            enc = parse_encoding(Context("config.json"), {"otype": spelling, **cfg}, n_dims, "encoding", 0)
            assert enc.padded > 0 or otype == "empty", otype
    with pytest.raises(ConvertError, match="Tiled grids are not supported"):
        parse_encoding(Context("config.json"), {"otype": "TiledGrid"}, 2, "encoding", 0)
