"""Drop-ins for the material editors of game engines: a network's HLSL (weights as literals) as a
Unity Shader Graph Custom Function (File mode) and as the body of an Unreal Custom expression node,
with each engine's calling conventions written down. These engines do not run here: ``check``
runs the very text written, wrapped as the engine wraps it, through the HLSL driver against torch.
"""
from __future__ import annotations

from .drop_in import ENGINE_TEXT, DropIn, check_drop_in, drop_in

ENGINES = tuple(ENGINE_TEXT)

__all__ = ["ENGINES", "DropIn", "check_drop_in", "drop_in"]
