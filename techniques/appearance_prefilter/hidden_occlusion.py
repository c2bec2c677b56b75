"""Hidden occlusion on its own (the ``slabs`` scene): what the learnt coverage masks buy over a
statistical aggregate. The asset is marched by the torch twin (march.py) twice per scale, once with
its decoded 8x8 coverage masks (correlated transmittance along the beam, as shipped) and once with
each mask replaced by its mean (uncorrelated alpha, what an SGGX/EGGX-style aggregate assumes);
both against the full-geometry reference. Sun shadows are off on both sides (the reference casts no
shadow rays, the march reads no shadow map) so that only the occlusion within the beam differs.
Views: the scene's camera, and the same orbit turned to yaw 0, looking along the slab planes, where
the gaps line up at every depth."""
from __future__ import annotations

import numpy as np
import torch

# (label, yaw override): the scene's own view, and the view along the slab planes
VIEWS = (("scene camera", None), ("along the slabs (yaw 0)", 0.0))


class MeanMask(torch.nn.Module):
    """The decoder with each coverage mask (its first mask² outputs) replaced by the mask's mean."""

    def __init__(self, decoder, lanes: int):
        super().__init__()
        self.decoder, self.lanes = decoder, lanes

    def forward(self, x):
        y = self.decoder(x).clone()
        y[:, :self.lanes] = y[:, :self.lanes].mean(-1, keepdim=True)
        return y


def measure(bundle, geometry, camera, scales, *, spp: int, sun_dir, sun_radiance: float, sh, image_side) -> list[dict]:
    """Rows per (view, scale): MSE of the masked and the mean-alpha march against the reference."""
    from inshade.scene.camera import camera_from_dict

    from . import march
    from .reference import render_reference

    args = march.bundle_args(bundle)
    mean_alpha = dict(args, decoder=MeanMask(args["decoder"], args["mask"] ** 2))
    rows = []
    for label, yaw in VIEWS:
        cam = camera if yaw is None else camera_from_dict(dict(camera.to_dict(), yaw=yaw))
        for s in scales:
            side = image_side(cam, s)
            ref = render_reference(geometry, camera=cam.to_dict(), size=(side, side), spp=spp, sun_dir=sun_dir,
                                   sun_radiance=sun_radiance, env_sh=sh, shadows=False, seed=s)
            mse = {}
            for name, a in (("masks", args), ("mean_alpha", mean_alpha)):
                img = march.render_prefiltered(**a, camera=cam.uniforms(side, side), width=side, height=side,
                                               sun_dir=sun_dir, sun_radiance=sun_radiance, sh=sh, force_scale=s)
                mse[name] = float(np.mean((img[..., :3].astype(np.float64) - ref) ** 2))
            rows.append({"view": label, "scale": s, "size": side, "mse_masks": mse["masks"],
                         "mse_mean_alpha": mse["mean_alpha"], "ratio": mse["mean_alpha"] / mse["masks"]})
    return rows
