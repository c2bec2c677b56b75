"""The UV-free hashed per-triangle feature hierarchy (Walloner 2024; models/mesh_features.py has the exact rules)"""
