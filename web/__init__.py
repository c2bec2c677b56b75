"""The asset in a web page: ``inshade export-web`` writes a static WebGL2 / WebGPU viewer of any asset.

``export.export_web`` sets the asset up through the GL runtime with ES 3.00 programs planned
against WebGL2's limits (``limits.WEBGL2``), then writes what its draw binds (programs, network
resources, scene and environment textures, shadow maps, the mesh, uniforms) as files the page's
JavaScript (``page/inshade.js``) replays; ``webgpu`` translates the same programs to WGSL for the
page's WebGPU path (``page/webgpu_backend.js``). ``serve`` serves such a folder on localhost; ``browser``
drives headless Chromium (tests and the bench). Torch-free.
"""
