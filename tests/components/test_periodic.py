"""sin / cos past pi: codegen reduces the argument by 2 pi (lib/activations' Cody-Waite split) where
the plan's bound of the argument passes pi, and calls the built-in as it is below that. The reduced
form must be as exact as torch's sinf / cosf of the same float32 argument across |k| < 2^12 turns,
and no worse than the built-in beyond."""
from __future__ import annotations

import re

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from inshade.codegen import generate
from inshade.components.elementwise.torch_twin import Cos, Sin
from inshade.components.encodings.torch_twin import Frequency
from inshade.models import GraphModule

from parity import glsl_eval, parity_settings, torch_reference, uniform_inputs

# the reduced argument is within an ulp or two of the exact one; torch's float32 product and the
# shader's are the same rounding, so the two agree to a few float32 ulps of 1
EXACT = 5e-7


def _periodic(omega0: float):
    g = GraphModule([("x", 4)])
    g.output("s", g.add("sin", Sin(omega0), "x"))
    g.output("c", g.add("cos", Cos(omega0), "x"))
    return g.export("periodic")


@parity_settings(12)
@given(omega0=st.sampled_from([4.0, 30.0, 100.0]), reach=st.sampled_from([1.0, 30.0, 250.0, 4000.0]),
       seed=st.integers(0, 2 ** 31 - 1))
def test_reduced_sin_and_cos_match_torch_at_large_arguments(gl, omega0, reach, seed):
    """omega0 * x up to 4e5: inside the split's range (|x| < 25,700) the reduced built-in agrees with
    torch to a few ulps; past it the built-in gets the argument as it is (never a wrong turn count)."""
    bundle = _periodic(omega0)
    x = uniform_inputs(seed, 512, 4, -reach, reach)
    x[:8] = np.float32(np.pi / omega0) * np.arange(1, 9, dtype=np.float32)[:, None]   # at multiples of pi
    out, ref = glsl_eval(gl, bundle, x), torch_reference(bundle, x)
    inside = np.abs(omega0 * x) < 25_000
    err = np.abs(out - ref)
    assert err[:, :4][inside].max(initial=0.0) <= EXACT and err[:, 4:][inside].max(initial=0.0) <= EXACT, err.max()


def _calls(chunk: str) -> list[str]:
    return re.findall(r"\b(inshade_sin|inshade_cos|sin|cos)\(", chunk)


def test_the_reduction_is_emitted_only_where_the_plan_bound_passes_pi():
    small, large = _periodic(1.0), _periodic(30.0)   # inputs assumed in [-1, 1]: bounds 1 and 30
    assert _calls(generate(small).chunk) == ["sin", "cos"]
    assert _calls(generate(large).chunk) == ["inshade_sin", "inshade_cos"]
    g = GraphModule([("x", 2)])
    g.output("y", g.add("enc", Frequency(3, include_input=False), "x"))
    # 2^k pi |x|: pi (k = 0, the built-in), 2 pi and 4 pi (reduced), for sin then cos
    assert _calls(generate(g.export("freq")).chunk) == ["sin"] * 2 + ["inshade_sin"] * 4 + ["cos"] * 2 + \
        ["inshade_cos"] * 4


def test_a_frequency_encoding_matches_torch_past_pi(gl):
    g = GraphModule([("x", 1)])
    g.output("y", g.add("enc", Frequency(10), "x"))   # 2^9 pi |x|: arguments up to 1608
    bundle = g.export("freq10")
    x = uniform_inputs(1, 1024, 1)
    err = np.abs(glsl_eval(gl, bundle, x) - torch_reference(bundle, x)).max()
    assert err <= EXACT, err
