"""The plan report: what the generated code costs per pixel and where the weights live."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field


@dataclass
class Plan:
    network: str
    target: str
    rows: list
    resources: list
    limits: dict = field(default_factory=dict)   # GL limit -> {"uses", "limit", "source"}
    calls: int = 1   # evaluations per pixel in the caller's loop (a march's steps): an upper bound

    @property
    def pixel_flops(self) -> int:
        """FLOPs one pixel may spend in this network: per evaluation times ``calls`` (an upper
        bound: a march that stops early spends less)."""
        return self.totals()["flops"] * self.calls

    def totals(self) -> dict:
        keys = ("params", "flops", "fetches", "uniform_bytes", "texture_bytes")
        return {k: sum(getattr(r, k) for r in self.rows) for k in keys}

    def to_dict(self) -> dict:
        return {"network": self.network, "target": self.target, "totals": self.totals(),
                "nodes": [asdict(r) for r in self.rows], "limits": self.limits, "calls": self.calls}

    def report(self) -> str:
        head = ("node", "type", "shape", "storage", "params", "FLOPs/px", "fetches/px", "UBO B", "tex B")
        rows = [(r.node, r.type, r.shape, r.storage, r.params, r.flops, r.fetches,
                 r.uniform_bytes, r.texture_bytes) for r in self.rows]
        t = self.totals()
        rows.append(("total", "", "", "", t["params"], t["flops"], t["fetches"], t["uniform_bytes"],
                     t["texture_bytes"]))
        widths = [max(len(str(x)) for x in col) for col in zip(head, *rows)]
        fmt = "  ".join("{:<%d}" % w for w in widths)
        out = [f"plan for '{self.network}' (GLSL {self.target})", fmt.format(*head)]
        out += [fmt.format(*map(str, r)) for r in rows]
        if self.calls != 1:
            out.append(f"evaluated up to {self.calls} times per pixel: {self.pixel_flops} FLOPs/px")
        whys = [f"  {r.node}: {r.storage}: {r.why}" for r in self.rows if r.why]
        if whys:
            out += ["storage choices:"] + whys
        if self.limits:
            out.append("GL limits (uses / limit, from):")
            out += [f"  {k}: {v['uses']} / {v['limit']} ({v['source']})" for k, v in self.limits.items()]
        return "\n".join(out)
