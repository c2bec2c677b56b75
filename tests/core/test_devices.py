"""``--device auto|cpu|cuda[:N]`` (inshade/devices.py) and its wiring into every trainer.

No GPU here: the CUDA paths are checked by patching what torch reports, the trainers by asking
for CUDA (one ``inshade: error: --device cuda...`` line, exit status 2, before any work), and CPU
determinism by two identical runs of a cheap trainer.
"""
from __future__ import annotations


import numpy as np
import pytest
import torch

from inshade.bundle import load
from inshade.devices import DeviceError, add_device_argument, check_spec, resolve_device
from inshade.technique import techniques


# ---------------------------------------------------------------------------------------------
# inshade/devices.py

@pytest.mark.parametrize("spec", ["auto", "cpu", "cuda", "cuda:0", "cuda:3", "cuda:12"])
def test_check_spec_accepts(spec):
    assert check_spec(spec) == spec


@pytest.mark.parametrize("spec", ["", "gpu", "CUDA", "cuda:", "cuda:x", "cuda:-1", "cpu:0", "mps", " cpu", "cuda0", None, 0])
def test_check_spec_refuses(spec):
    with pytest.raises(DeviceError, match="is not one of auto, cpu, cuda, cuda:N"):
        check_spec(spec)


def test_resolve_here_is_the_cpu():
    assert not torch.cuda.is_available()   # this machine; the CUDA cases below patch torch
    assert resolve_device("auto") == torch.device("cpu")
    assert resolve_device("cpu") == torch.device("cpu")


@pytest.mark.parametrize("spec", ["cuda", "cuda:3"])
def test_cuda_without_cuda_is_one_clear_error(spec):
    with pytest.raises(DeviceError) as info:
        resolve_device(spec)
    message = str(info.value)
    assert message.startswith(f"--device {spec}: this torch build sees no CUDA device")
    assert "use --device cpu or auto" in message and "\n" not in message


def test_bad_spelling_is_refused_before_torch_is_asked(monkeypatch):
    def boom():
        raise AssertionError("asked torch for a spelling error")
    monkeypatch.setattr(torch.cuda, "is_available", boom)
    with pytest.raises(DeviceError, match="'gpu' is not one of"):
        resolve_device("gpu")


@pytest.fixture
def two_gpus(monkeypatch):
    """torch reporting two CUDA devices (torch.device objects need no real device)."""
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 2)


def test_auto_is_cuda_when_torch_sees_it(two_gpus):
    assert resolve_device("auto") == torch.device("cuda")
    assert resolve_device("cpu") == torch.device("cpu")


def test_cuda_index_is_checked_against_the_count(two_gpus):
    assert resolve_device("cuda") == torch.device("cuda", 0)
    assert resolve_device("cuda:1") == torch.device("cuda", 1)
    with pytest.raises(DeviceError, match=r"^--device cuda:2: torch sees 2 CUDA device\(s\) \(cuda:0\.\.cuda:1\)$"):
        resolve_device("cuda:2")


def test_argparse_option(capsys):
    import argparse

    parser = argparse.ArgumentParser(prog="t")
    add_device_argument(parser)
    assert parser.parse_args([]).device == "auto"
    assert parser.parse_args(["--device", "cuda:1"]).device == "cuda:1"
    with pytest.raises(SystemExit) as info:
        parser.parse_args(["--device", "gpu"])
    assert info.value.code == 2
    assert "'gpu' is not one of auto, cpu, cuda, cuda:N" in capsys.readouterr().err


# ---------------------------------------------------------------------------------------------
# every trainer: --device cuda here is one error line, exit 2, before any work

# The arguments argparse requires of each trainer (the paths need not exist: the device is
# resolved first). A trainer missing here fails the coverage test below.
MINIMAL_ARGS = {
    "neural_image": [],
    "neural_sdf": [],
    "prt": ["--sdf", "no_such.json", "--out", "{tmp}/prt"],
    "di_texture": ["skimage:astronaut", "--out", "{tmp}/di_texture"],
    "di_pbr_set": ["--out", "{tmp}/di_pbr_set"],
    "di_footprint": ["--out", "{tmp}/di_footprint"],
    "di_brdf": ["ggx", "--out", "{tmp}/di_brdf"],
    "di_sdf": ["--mesh", "no_such.ply", "--out", "{tmp}/di_sdf"],
    "di_shading": ["--out", "{tmp}/di_shading"],
    "di_radiance_field": ["--out", "{tmp}/di_radiance_field"],
    "neural_appearance": [],
    "uvfree_material": [],
    "appearance_prefilter": [],
    "hash_grid": ["image", "-o", "{tmp}/hash_grid"],
}
TRAINERS = sorted(t.name for t in techniques() if t.train)


def test_every_trainer_is_in_the_table():
    assert TRAINERS and set(TRAINERS) == set(MINIMAL_ARGS)


@pytest.mark.parametrize("name", TRAINERS)
def test_trainer_refuses_cuda_it_does_not_have(name, tmp_path, monkeypatch, capsys):
    """In-process (torch is imported once for all ten; the CLI path is the same ``inshade.cli.main``)."""
    from inshade.cli import main

    monkeypatch.chdir(tmp_path)
    args = [a.format(tmp=tmp_path) for a in MINIMAL_ARGS[name]]
    code = main(["train", name, *args, "--device", "cuda"])
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert code == 2, err[-2000:]
    assert len(lines) == 1 and lines[0].startswith("inshade: error: --device cuda: "), err[-2000:]
    assert list(tmp_path.iterdir()) == []    # nothing written


# ---------------------------------------------------------------------------------------------
# CPU determinism: the same seed, bit-identical bundles; the resolved device is recorded

def test_cpu_runs_are_bit_identical(tmp_path):
    from inshade.techniques.neural_image.train import main

    base = ["--steps", "12", "--size", "16", "--levels", "4:4,16:1", "--batch", "128", "--seed", "3"]
    assert main([*base, "--out", str(tmp_path / "a"), "--device", "cpu"]) == 0
    assert main([*base, "--out", str(tmp_path / "b")]) == 0          # auto: the CPU here
    a, b = load(tmp_path / "a"), load(tmp_path / "b")
    assert sorted(a.tensors) == sorted(b.tensors)
    for k in a.tensors:
        assert np.array_equal(a.tensors[k], b.tensors[k]), k
    for bundle in (a, b):
        assert bundle.meta["provenance"]["device"] == "cpu"
        assert bundle.meta["metrics"]["device"] == "cpu"
