"""One printer per shading language over the lowered code of codegen/ir.py (codegen/targets.py
names which printer serves which target)."""
