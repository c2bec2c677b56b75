"""Every shipped asset renders bit-identical to the record written before the technique plug-in
refactor (tests/shipped_renders.py): moving code between packages must not move a pixel."""
from __future__ import annotations

import numpy as np
import pytest

from shipped_renders import CASES, RECORD, key, render_case


@pytest.fixture(scope="module")
def record():
    with np.load(RECORD) as data:
        return {k: data[k] for k in data.files}


def test_record_covers_every_case(record):
    assert sorted(record) == sorted(key(a, s) for a, s in CASES)


@pytest.mark.parametrize("asset,settings", CASES, ids=[key(a, s) for a, s in CASES])
def test_shipped_asset_renders_bit_identical(gl, record, asset, settings):
    image = render_case(asset, settings)
    want = record[key(asset, settings)]
    assert image.shape == want.shape
    diff = np.abs(image.astype(np.float64) - want)
    assert np.array_equal(image, want), (f"{key(asset, settings)}: {int((diff > 0).sum())} values differ, "
                                         f"max {diff.max():.3g}")
