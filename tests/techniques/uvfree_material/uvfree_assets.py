"""uvfree_material assets trained at test time: the quick preset, without the preview picture or the
progress bar."""
from __future__ import annotations


def train_quick(out, **options):
    """The asset folder ``out``, trained by the quick preset with the trainer's ``options``."""
    from inshade.techniques.uvfree_material.train import train

    return train(preset="quick", out=out, write_preview=False, progress=False, **options)
