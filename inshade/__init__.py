"""inshade: networks trained in PyTorch, running inside OpenGL fragment shaders.

``inshade.export(module, example_input, folder)`` turns a torch module into a bundle (checked
against the module through the GL driver); ``inshade.check(source, bundle, inputs)`` measures a
bundle against its source. Both import torch only when called: the runtime stays torch-free.
"""
from inshade.notebook import show  # Jupyter: an asset's page; in a notebook bundles and scenes draw themselves


def export(module, example_input, folder, **options):
    """See ``inshade.convert.export.export``."""
    from inshade.convert.export import export as _export

    return _export(module, example_input, folder, **options)


def check(source, bundle, inputs, **options):
    """See ``inshade.convert.check.check``."""
    from inshade.convert.check import check as _check

    return _check(source, bundle, inputs, **options)
