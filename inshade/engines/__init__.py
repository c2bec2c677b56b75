"""Drop-ins for the material editors of game engines: a network's HLSL (weights as literals, or as
image files the engine imports) as a Unity Shader Graph Custom Function (File mode) and as the body
of an Unreal Custom expression node, with each engine's calling and import conventions written down.
These engines do not run here: ``check`` runs the very text written, wrapped as the engine wraps it,
with its images read back as the engine lays them in memory, through the HLSL driver against torch.
"""
from __future__ import annotations

from .drop_in import ENGINE_TEXT, DropIn, check_drop_in, drop_in, readme

ENGINES = tuple(ENGINE_TEXT)

__all__ = ["ENGINES", "DropIn", "check_drop_in", "drop_in", "readme"]
