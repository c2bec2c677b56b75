"""Component types of the bundle graph, one folder each (components/registry.py says what a folder
holds). A new component is a folder here plus its name in ``BUILTIN``; a plug-in folder elsewhere
is one ``register_folder(path)`` call (or a path in ``INSHADE_COMPONENTS``).
"""
from __future__ import annotations

from . import registry
from .registry import RegistryError, register_folder
from .spec import COMPONENTS, MAX_WIDTH, ComponentError, ComponentSpec, Param, TensorSpec, check_node, resolve_params

BUILTIN = ("dense", "elementwise", "feature_axis", "encodings", "one_blob", "lookup_array", "latent_pyramid",
           "shading_frames", "proxy_params", "mesh_features", "grids", "sparse_voxels")

for _name in BUILTIN:
    registry.add_folder(f"{__name__}.{_name}", registry.BUILTIN_ROOT / _name)
registry.load("spec")

from .elementwise.spec import ACTIVATIONS, GELU_FORMS, PARTIAL_ELEMENTWISE, STEPPED_ELEMENTWISE  # noqa: E402
from .feature_axis.spec import MAX_GATHER_ROWS, REDUCE_OPS  # noqa: E402
from .grids.spec import GRID_KINDS, grid_node_levels  # noqa: E402
from .lookup_array.spec import LUT_BITS  # noqa: E402
from .proxy_params.spec import PROXY_PARAMS  # noqa: E402
from .sparse_voxels.spec import check_voxel_tables  # noqa: E402

__all__ = ["ACTIVATIONS", "BUILTIN", "COMPONENTS", "GELU_FORMS", "GRID_KINDS", "LUT_BITS", "MAX_GATHER_ROWS",
           "MAX_WIDTH", "PARTIAL_ELEMENTWISE", "PROXY_PARAMS", "REDUCE_OPS", "STEPPED_ELEMENTWISE", "ComponentError",
           "ComponentSpec", "Param", "RegistryError", "TensorSpec", "check_node", "check_voxel_tables",
           "grid_node_levels", "register_folder", "registry", "resolve_params"]
