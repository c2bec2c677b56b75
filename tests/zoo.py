"""A zoo of networks written in plain torch (no inshade classes), as users write them: each entry is
(module, example input). Together they use every op inshade.export lowers (tests/convert/test_export.py
checks the coverage against the handler table)."""
from __future__ import annotations

import math

import torch
import torch.nn as nn
import torch.nn.functional as F


def _seeded(seed):
    torch.manual_seed(seed)


class Plain(nn.Module):
    """nn.Sequential with the everyday activations."""

    def __init__(self):
        super().__init__()
        self.net = nn.Sequential(nn.Linear(3, 32), nn.ReLU(), nn.Linear(32, 32), nn.Tanh(), nn.Linear(32, 16),
                                 nn.LeakyReLU(0.2), nn.Linear(16, 4), nn.Sigmoid())

    def forward(self, x):
        return self.net(x)


class Siren(nn.Module):
    """SIREN (Sitzmann et al. 2020): sin(omega0 * (W x + b)), omega0 = 30."""

    def __init__(self, hidden=32, layers=3, omega0=30.0):
        super().__init__()
        self.omega0 = omega0
        dims = [2] + [hidden] * layers
        self.layers = nn.ModuleList(nn.Linear(a, b) for a, b in zip(dims, dims[1:]))
        with torch.no_grad():
            self.layers[0].weight.uniform_(-1 / 2, 1 / 2)
            for layer in self.layers[1:]:
                bound = math.sqrt(6 / layer.in_features) / omega0
                layer.weight.uniform_(-bound, bound)
        self.out = nn.Linear(hidden, 3)

    def forward(self, uv):
        h = uv
        for layer in self.layers:
            h = torch.sin(self.omega0 * layer(h))
        return self.out(h)


class NerfMLP(nn.Module):
    """A NeRF-style MLP: the positional encoding written in forward, a skip that concatenates the
    encoded input again, a density head and a view-dependent colour head (split, narrow, chunk)."""

    def __init__(self, freqs=6, width=32):
        super().__init__()
        self.freqs = freqs
        enc = 3 + 6 * freqs
        self.l0, self.l1 = nn.Linear(enc, width), nn.Linear(width, width)
        self.l2 = nn.Linear(width + enc, width + 1)
        self.view = nn.Linear(width + 3 + 12, width // 2)
        self.rgb = nn.Linear(width // 2, 3)

    def encode(self, x, n):
        return torch.cat([x] + [f(x * 2.0 ** k * math.pi) for k in range(n) for f in (torch.sin, torch.cos)], -1)

    def forward(self, xd):
        x, d = xd.split([3, 3], dim=-1)
        e = self.encode(x, self.freqs)
        h = F.relu(self.l1(F.relu(self.l0(e))))
        h = self.l2(torch.cat([h, e], -1))
        sigma, feat = h.narrow(-1, 0, 1), h[:, 1:]
        de = self.encode(d, 2)
        v = F.relu(self.view(torch.cat([feat, de], -1)))
        rgb = torch.sigmoid(self.rgb(v))
        r, g, b = rgb.chunk(3, dim=-1)
        return torch.cat([r, g, b, F.softplus(sigma)], -1)


class ResidualLN(nn.Module):
    """Residual blocks with LayerNorm and GELU (erf), nested modules."""

    class Block(nn.Module):
        def __init__(self, width):
            super().__init__()
            self.norm = nn.LayerNorm(width)
            self.fc1, self.fc2 = nn.Linear(width, 2 * width), nn.Linear(2 * width, width)

        def forward(self, x):
            return x + self.fc2(F.gelu(self.fc1(self.norm(x))))

    def __init__(self, width=16):
        super().__init__()
        self.inp = nn.Linear(4, width)
        self.blocks = nn.Sequential(*[self.Block(width) for _ in range(2)])
        self.head = nn.Sequential(nn.LayerNorm(width, elementwise_affine=False), nn.Linear(width, 2))

    def forward(self, x):
        return self.head(self.blocks(self.inp(x)))


class BatchNormDropout(nn.Module):
    """BatchNorm1d in eval mode and Dropout: folded away; ELU, SELU-style scaling."""

    def __init__(self):
        super().__init__()
        self.net = nn.Sequential(nn.Linear(5, 24), nn.BatchNorm1d(24), nn.ELU(0.7), nn.Dropout(0.3),
                                 nn.Linear(24, 12), nn.BatchNorm1d(12), nn.SiLU(), nn.Linear(12, 3))
        with torch.no_grad():
            for m in self.net:
                if isinstance(m, nn.BatchNorm1d):
                    m.running_mean.uniform_(-0.5, 0.5)
                    m.running_var.uniform_(0.5, 2.0)
                    m.weight.uniform_(0.5, 1.5)
                    m.bias.uniform_(-0.2, 0.2)
        self.eval()

    def forward(self, x):
        return self.net(x)


class Activations(nn.Module):
    """Softplus (beta, threshold), GELU tanh form, Mish, Hardswish, ReLU6, abs, clamp, exp, cos."""

    def __init__(self):
        super().__init__()
        self.a, self.b = nn.Linear(3, 16), nn.Linear(16, 16)
        self.c = nn.Linear(16, 8)

    def forward(self, x):
        h = F.softplus(self.a(x), beta=2.0, threshold=5.0)
        h = F.gelu(self.b(h), approximate="tanh") + F.mish(h) - F.hardswish(h) + F.relu6(4 * h)
        y = self.c(h)
        return torch.cat([torch.exp(torch.clamp(y[:, :2], -3, 2)), y[:, 2:4].abs(), torch.cos(y[:, 4:6]),
                          F.elu(y[:, 6:]) * 1.0507], -1)


class Heads(nn.Module):
    """ModuleList trunk, several heads returned as a tuple, a dict inside."""

    def __init__(self):
        super().__init__()
        self.trunk = nn.ModuleList([nn.Linear(2, 16), nn.Linear(16, 16)])
        self.heads = nn.ModuleDict({"colour": nn.Linear(16, 3), "alpha": nn.Linear(16, 1)})

    def forward(self, x):
        for layer in self.trunk:
            x = F.relu(layer(x))
        return torch.sigmoid(self.heads["colour"](x)), torch.sigmoid(self.heads["alpha"](x))


class GridTexture(nn.Module):
    """A neural texture: a learned 2D feature grid read with grid_sample (bilinear, align_corners
    True, border) + a small MLP decoder."""

    def __init__(self, channels=8, res=16):
        super().__init__()
        self.grid = nn.Parameter(torch.randn(1, channels, res, res) * 0.5)
        self.mlp = nn.Sequential(nn.Linear(channels + 2, 16), nn.ReLU(), nn.Linear(16, 3))

    def forward(self, uv):
        g = uv * 2 - 1
        feat = F.grid_sample(self.grid, g.view(1, -1, 1, 2), mode="bilinear", padding_mode="border",
                             align_corners=True)            # [1, C, B, 1]
        feat = feat[0, :, :, 0].t()                         # [B, C]
        return self.mlp(torch.cat([feat, uv], -1))


class Grid3D(nn.Module):
    """A 3D grid (align_corners False, zeros padding) sampled at two offsets per point, with norm,
    sum and division between branches."""

    def __init__(self):
        super().__init__()
        self.grid = nn.Parameter(torch.randn(1, 4, 6, 5, 7) * 0.5)
        self.offset = nn.Parameter(torch.tensor([[0.1, -0.2, 0.05]]))

    def forward(self, p):
        pts = torch.stack([p, p + self.offset], dim=1)     # [B, 2, 3]
        f = F.grid_sample(self.grid, pts.view(1, 1, -1, 2, 3), align_corners=False, padding_mode="zeros")
        f = f.permute(0, 2, 3, 4, 1).reshape(-1, 8)         # [B, 2 * 4]
        n = p.norm(dim=-1, keepdim=True)
        s = f.sum(dim=-1, keepdim=True)
        return torch.cat([f / (1 + n), s - n * 2, f.mean(-1, keepdim=True)], -1)


class Branches(nn.Module):
    """Elementwise ops between branches and with constants; x @ W with a parameter, F.linear,
    torch.addmm."""

    def __init__(self):
        super().__init__()
        self.w = nn.Parameter(torch.randn(4, 8) * 0.5)
        self.w2 = nn.Parameter(torch.randn(8, 8) * 0.3)
        self.b2 = nn.Parameter(torch.randn(8) * 0.1)
        self.bias = nn.Parameter(torch.randn(8) * 0.1)

    def forward(self, x):
        a = x @ self.w                       # matmul with a parameter
        b = F.linear(a, self.w2, self.b2)
        c = torch.addmm(self.bias, a, self.w2.t())
        d = (a * b - c) / (2.0 + torch.sigmoid(c)) + 3.0 / (1.5 + a.abs())
        return torch.cat([d * 0.5 + 1, 1 - a, a / 3.0, b - 0.25], -1)


class Layouts(nn.Module):
    """view / reshape / permute / transpose / unsqueeze / expand / stack / flip / index_select, and
    the vectorised frequency encoding (x[..., None] * freqs).flatten."""

    def __init__(self):
        super().__init__()
        self.register_buffer("freqs", 2.0 ** torch.arange(4) * math.pi)
        self.fc = nn.Linear(3 * 4 * 2 + 3, 12)
        self.out = nn.Linear(12, 6)

    def forward(self, x):
        xb = x[..., None] * self.freqs                     # [B, 3, 4]
        enc = torch.cat([torch.sin(xb), torch.cos(xb)], -1).flatten(1)
        h = F.relu(self.fc(torch.cat([x, enc], -1)))      # [B, 12]
        h3 = h.view(-1, 3, 4).transpose(1, 2)             # [B, 4, 3]
        h3 = h3.flip(1).permute(0, 2, 1).reshape(h.shape[0], -1)
        idx = torch.tensor([0, 5, 2, 2, 11, 7])
        picked = h3.index_select(1, idx)
        stacked = torch.stack([picked[:, 0], picked[:, 1]], dim=-1)
        return self.out(h3) + picked.unsqueeze(1).expand(-1, 1, 6).squeeze(1), stacked


class SoftmaxGate(nn.Module):
    """Softmax over features as mixture weights, torch.where on a comparison, amax, pow, sqrt, rsqrt."""

    def __init__(self):
        super().__init__()
        self.logits, self.values = nn.Linear(3, 4), nn.Linear(3, 4)

    def forward(self, x):
        w = torch.softmax(self.logits(x), dim=-1)
        v = self.values(x)
        gated = torch.where(v > 0, v, 0.1 * v)
        top = torch.amax(gated, dim=-1, keepdim=True)
        r = torch.sqrt(v.pow(2) + 1) * torch.rsqrt(w + 1)
        return torch.cat([(w * gated).sum(-1, keepdim=True), top, r], -1)


class SdfNet(nn.Module):
    """An SDF network: a sphere plus a learned residual (Softplus MLP, the neural-SDF habit)."""

    def __init__(self):
        super().__init__()
        self.net = nn.Sequential(nn.Linear(3, 32), nn.Softplus(beta=10), nn.Linear(32, 32), nn.Softplus(beta=10),
                                 nn.Linear(32, 1))
        with torch.no_grad():
            self.net[-1].weight.mul_(0.05)
            self.net[-1].bias.zero_()

    def forward(self, p):
        return p.norm(dim=-1, keepdim=True) - 0.6 + self.net(p)


def zoo() -> dict:
    """name -> (module in eval mode, example input)."""
    _seeded(0)
    u = lambda n, d: torch.rand(n, d) * 2 - 1  # noqa: E731
    entries = {
        "plain": (Plain(), u(64, 3)),
        "siren": (Siren(), torch.rand(64, 2)),
        "nerf": (NerfMLP(), torch.cat([u(64, 3), F.normalize(torch.randn(64, 3), dim=-1)], -1)),
        "residual_ln": (ResidualLN(), u(64, 4)),
        "batchnorm_dropout": (BatchNormDropout(), u(64, 5)),
        "activations": (Activations(), u(64, 3)),
        "heads": (Heads(), torch.rand(64, 2)),
        "grid_texture": (GridTexture(), torch.rand(64, 2)),
        "grid3d": (Grid3D(), u(64, 3) * 1.1),
        "branches": (Branches(), u(64, 4)),
        "layouts": (Layouts(), u(64, 3)),
        "softmax_gate": (SoftmaxGate(), u(64, 3)),
        "sdf": (SdfNet(), u(64, 3)),
    }
    for module, _ in entries.values():
        module.eval()
    return entries


def exported(folder_for) -> dict:
    """name -> (module, bundle, inputs [N, in_dim]) of every zoo network exported (unchecked) into the
    folder ``folder_for(name)`` gives."""
    import inshade
    from inshade.bundle import load

    out = {}
    for name, (module, example) in zoo().items():
        folder = folder_for(name)
        inshade.export(module, example, folder, check=False)
        out[name] = (module, load(folder), example.numpy().reshape(len(example), -1))
    return out
