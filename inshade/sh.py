"""Real orthonormal spherical harmonics, bands l = 0..4, index l*l + l + m.

One table of monomial terms generates the numpy/torch evaluation and the GLSL code, so the
two cannot drift apart. Convention: Condon-Shortley phase included (as tiny-cuda-nn and
Sloan's "Stupid SH tricks"); the polynomials assume a unit direction.
"""
from __future__ import annotations

import numpy as np

# Each coefficient is a list of (constant, (power of x, power of y, power of z)).
_A = 0.59004358992664352
_B = 0.45704579946446572
_C = 1.7701307697799304
_D = 0.94617469575756008
_E = 0.66904654355728921
_F = 0.47308734787878004
SH_TERMS: list[list[tuple[float, tuple[int, int, int]]]] = [
    [(0.28209479177387814, (0, 0, 0))],
    [(-0.48860251190291987, (0, 1, 0))],
    [(0.48860251190291987, (0, 0, 1))],
    [(-0.48860251190291987, (1, 0, 0))],
    [(1.0925484305920792, (1, 1, 0))],
    [(-1.0925484305920792, (0, 1, 1))],
    [(0.94617469575755997, (0, 0, 2)), (-0.31539156525251999, (0, 0, 0))],
    [(-1.0925484305920792, (1, 0, 1))],
    [(0.54627421529603959, (2, 0, 0)), (-0.54627421529603959, (0, 2, 0))],
    [(-3 * _A, (2, 1, 0)), (_A, (0, 3, 0))],
    [(2.8906114426405538, (1, 1, 1))],
    [(_B, (0, 1, 0)), (-5 * _B, (0, 1, 2))],
    [(5 * 0.3731763325901154, (0, 0, 3)), (-3 * 0.3731763325901154, (0, 0, 1))],
    [(_B, (1, 0, 0)), (-5 * _B, (1, 0, 2))],
    [(1.4453057213202769, (2, 0, 1)), (-1.4453057213202769, (0, 2, 1))],
    [(-_A, (3, 0, 0)), (3 * _A, (1, 2, 0))],
    [(2.5033429417967046, (3, 1, 0)), (-2.5033429417967046, (1, 3, 0))],
    [(-3 * _C, (2, 1, 1)), (_C, (0, 3, 1))],
    [(7 * _D, (1, 1, 2)), (-_D, (1, 1, 0))],
    [(3 * _E, (0, 1, 1)), (-7 * _E, (0, 1, 3))],
    [(0.31735664074561293, (0, 0, 0)), (-3.1735664074561294, (0, 0, 2)), (3.7024941420321507, (0, 0, 4))],
    [(3 * _E, (1, 0, 1)), (-7 * _E, (1, 0, 3))],
    [(7 * _F, (2, 0, 2)), (-_F, (2, 0, 0)), (-7 * _F, (0, 2, 2)), (_F, (0, 2, 0))],
    [(-_C, (3, 0, 1)), (3 * _C, (1, 2, 1))],
    [(-3.7550144126950569, (2, 2, 0)), (0.62583573544917614, (4, 0, 0)), (0.62583573544917614, (0, 4, 0))],
]


def monomials(degree: int) -> list[tuple[int, int, int]]:
    """The distinct monomials the first degree**2 basis functions use, in a stable order."""
    return sorted({pw for terms in SH_TERMS[: degree * degree] for _, pw in terms})


def sh_basis(dirs, degree: int, xp=np):
    """Evaluates the basis at directions [..., 3] with numpy or torch (`xp`)."""
    x, y, z = dirs[..., 0], dirs[..., 1], dirs[..., 2]
    cols = []
    for terms in SH_TERMS[: degree * degree]:
        acc = 0.0
        for c, (a, b, e) in terms:
            acc = acc + c * (x ** a) * (y ** b) * (z ** e)
        cols.append(acc + 0.0 * x)
    return xp.stack(cols, -1)
