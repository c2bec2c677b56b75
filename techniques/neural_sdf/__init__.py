"""neural_sdf: an MLP SDF fitted to a watertight mesh, Lipschitz-bounded for a safe sphere-tracing
step; traced by the sdf technique's pass (scene.json ``"sdf": {"network": ...}``)."""
from inshade.technique import Technique, folder_fields

TECHNIQUE = Technique(
    name="neural_sdf",
    summary="an MLP SDF fitted to a mesh, traced in-shader",
    kinds=("neural_sdf",),
    **folder_fields(__name__, train="fit an MLP SDF to a watertight mesh"),
)
