"""The GL runtime (torch-free): context, programs, passes, scenes, the renderer, headless renders
and image IO. It names no technique: a scene's program is looked up in the technique registry
(inshade/technique.py) and its ``ProgramSpec`` says what to set up."""
