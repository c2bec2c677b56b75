"""A component is one folder plus one registration line. The toy_softsign plug-in
(tests/plugins/toy_softsign: spec, torch twin with its custom op, emitter, GLSL chunk, envelope rule,
torch-op lowering) goes through ``inshade.export``, codegen in every weight storage and the parity
rule, registered by ``register_folder`` alone. It runs in a fresh interpreter, as a user's program
would, so no other test sees the toy registered."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from inshade.components import COMPONENTS, registry

from parity import TOL
from test_architecture import ROOT

TESTS = Path(__file__).resolve().parents[1]
TOY = TESTS / "plugins" / "toy_softsign"
STORAGES = ("inline", "ubo", "texture")


def toy_session(folder: str) -> None:
    """In a fresh interpreter: register the folder, export a torch module using the toy, and print
    what came out (node types, the export's check line, the error in each storage) as JSON."""
    import contextlib
    import io

    import numpy as np
    import torch

    import inshade
    from inshade.bundle import load
    from inshade.components import register_folder
    from inshade.convert.check import check_inputs, evaluate, source_outputs

    register_folder(TOY)    # the one registration line
    from toy_softsign.torch_twin import ToySoftsign

    torch.manual_seed(0)
    net = torch.nn.Sequential(torch.nn.Linear(3, 16), ToySoftsign(0.5), torch.nn.Linear(16, 2))
    example = torch.rand(64, 3) * 2 - 1
    log = io.StringIO()
    with contextlib.redirect_stderr(log):
        inshade.export(net, example, folder)
    saved = load(folder)
    x = check_inputs(example.numpy(), seed=1)
    ref = np.asarray(source_outputs(net, [x], None), np.float64)
    errors = {}
    for storage in STORAGES:
        out, _, _ = evaluate(saved, x, storage=storage)
        errors[storage] = float(np.max(np.abs(np.asarray(out, np.float64) - ref) / np.maximum(1.0, np.abs(ref))))
    from inshade.codegen import generate
    from inshade.codegen.targets import TargetError

    try:   # a GLSL-only component: the other shading languages refuse it in one line
        generate(saved, target="wgsl")
        refusal = ""
    except TargetError as exc:
        refusal = str(exc)
    print(json.dumps({"types": [n.type for n in saved.nodes], "check": log.getvalue().strip().splitlines()[-1],
                      "errors": errors, "spread": float(np.ptp(ref)), "refusal": refusal}))


def test_a_component_folder_goes_through_export_codegen_and_parity(tmp_path, gl):
    code = (f"import sys; sys.path[:0] = [{str(Path(__file__).parent)!r}, {str(TESTS)!r}]; "
            "import test_component_folder as t; "
            f"t.toy_session({str(tmp_path / 'toy_net')!r})")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    got = json.loads(run.stdout.strip().splitlines()[-1])
    assert "toy_softsign" in got["types"], got["types"]          # lowered onto the toy, not its arithmetic
    assert got["check"].endswith("(rule 1e-05): ok"), got["check"]
    assert got["spread"] > 0.1                                    # the outputs vary: the comparison can fail
    assert set(got["errors"]) == set(STORAGES)
    assert "component 'toy_softsign' has no wgsl lowering" in got["refusal"] and "\n" not in got["refusal"]
    for storage, err in got["errors"].items():
        assert err <= TOL, f"{storage}: {err:.3g} > {TOL}"


def test_the_toy_is_named_nowhere_outside_its_folder_and_this_test():
    out = subprocess.run(["git", "grep", "-l", "toy_softsign"], cwd=ROOT, capture_output=True, text=True).stdout
    outside = [f for f in out.split() if not f.startswith("tests/plugins/toy_softsign/")
               and f != "tests/components/test_component_folder.py"]
    assert not outside, outside
    assert "toy_softsign" not in COMPONENTS      # registered only where a program asks for it


def test_a_name_registered_twice_is_refused_naming_both_places():
    from inshade.components.spec import ComponentSpec, same_width

    with pytest.raises(registry.RegistryError, match=r"'dense': spec registered twice \(inshade\.components\.dense\.spec and test_component_folder\)"):
        registry.add("spec", "dense", ComponentSpec("dense", "another dense", {}, out_dim=same_width),
                     where=__name__)
    assert COMPONENTS["dense"].doc.startswith("y = W x + b")


def test_every_built_in_component_has_each_runtime_concern():
    """Every spec has a torch twin, an emitter and an envelope rule, wherever it is defined."""
    import inshade.codegen  # noqa: F401  (loads the emitters)
    import inshade.envelope  # noqa: F401  (loads the rules)
    import inshade.models  # noqa: F401  (loads the twins)

    for concern in ("torch", "glsl", "envelope"):
        missing = sorted(set(COMPONENTS) - set(registry.table(concern)))
        assert not missing, f"{concern}: {missing}"
