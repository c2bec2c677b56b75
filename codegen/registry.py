"""GLSL emitters, registered under the bundle's component type names."""
from __future__ import annotations

EMITTERS: dict = {}


def emitter(*types: str):
    def deco(fn):
        for t in types:
            EMITTERS[t] = fn
        return fn
    return deco
