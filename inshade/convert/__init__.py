"""Ways in: a user's torch module (``export``) or ONNX file (``onnx_model``) becomes a bundle whose
GLSL is checked against the source (``check``). Importers never emit GLSL: they meet the rest of
inshade at the bundle. Needs torch (modules) or onnx (files); the runtime never imports this."""
