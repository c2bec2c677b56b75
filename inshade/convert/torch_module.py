"""A user's torch module -> bundle: capture with torch.export (torch.fx + make_fx where export
cannot), then walk the ATen graph, lowering each op by the lowering registered for it
(``@torch_op`` in ops/torch_*.py) onto components (lowering.py).

The module is traced at a batch of ``TRACE_BATCH`` rows (a prime no feature axis is likely to
share), so the batch axis of every tensor is the one of that size; the user's example rows are
kept for the parity check. Operations whose inputs are all constants (parameters, buffers,
literals, their transposes and products) are evaluated by torch itself and stay constants.
"""
from __future__ import annotations

import contextlib
import logging
import operator
import os
import traceback
from pathlib import Path

import numpy as np
import torch

from inshade.components import registry as component_registry

from .lowering import ConvertError, Feat, Lowering
from .ops import torch_activations, torch_arithmetic, torch_layers, torch_shapes  # noqa: F401 (they fill TORCH_OPS)
from .ops.common import Condition
from .ops.torch_values import floats, map_ints
from .registry import TORCH_OPS

component_registry.load("lowering")     # the component folders' own lowerings

HANDLERS = TORCH_OPS   # the ATen ops inshade.export lowers, by name

TRACE_BATCH = 97


class LeadingAxes(torch.nn.Module):
    """``module`` called on rows: each input [N, F] posed as [1, .., 1, N, F] (``lead`` batch axes),
    each output's leading axes flattened back to rows (the parity check feeds and compares rows)."""

    def __init__(self, module, lead: int):
        super().__init__()
        self.module, self.lead = module, lead

    def forward(self, *xs):
        out = self.module(*[x.reshape(*(1,) * (self.lead - 1), *x.shape) for x in xs])
        return torch.utils._pytree.tree_map(lambda t: t.reshape(-1, *t.shape[self.lead:]), out)


# --- capture ---------------------------------------------------------------------------------

@contextlib.contextmanager
def _quiet_torch():
    """torch.export logs graphs and hints on failures; the user gets one line from us instead."""
    logger = logging.getLogger("torch")
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        logger.setLevel(level)


def _user_frame(tb) -> str:
    """'file:line' of the innermost frame outside torch and inshade in a traceback, or ''."""
    torch_root = str(Path(torch.__file__).parent)
    ours = str(Path(__file__).resolve().parents[1])
    for frame in reversed(traceback.extract_tb(tb)):
        f = str(Path(frame.filename).resolve()) if os.path.exists(frame.filename) else frame.filename
        if not f.startswith((torch_root, ours)) and "<" not in frame.filename:
            return f"{_short(frame.filename)}:{frame.lineno}"
    return ""


def _short(path: str) -> str:
    try:
        return os.path.relpath(path)
    except ValueError:
        return path
    # (a relative path when under the working folder, else as given)


def capture(module: torch.nn.Module, args: tuple):
    """(graph module, {placeholder name: constant tensor}, [user input placeholder names])."""
    with _quiet_torch():
        try:
            ep = torch.export.export(module, args, strict=False)
        except Exception as exc:   # torch.export raises many types; each becomes one line below
            first = _classify(exc)
            if first is not None:
                raise ConvertError(first) from None
            return _capture_fx(module, args, exc)
    consts, user = {}, []
    sig = ep.graph_signature
    state = {**ep.state_dict, **ep.constants}
    for spec in sig.input_specs:
        name = spec.arg.name
        if spec.kind.name == "USER_INPUT":
            user.append(name)
        else:
            consts[name] = state[spec.target]
    return ep.graph_module, consts, user


def _classify(exc) -> str | None:
    """A refusal line for capture failures that no other tracer could fix, else None."""
    text = f"{type(exc).__name__}: {exc}"
    where = _user_frame(exc.__traceback__)
    if "data-dependent" in text or "DataDependent" in text:
        return (f"{where + ': ' if where else ''}data-dependent control flow (a Python `if`, loop or index on a "
                "tensor's value): a shader runs one program for every pixel; use torch.where-style arithmetic")
    return None


def _capture_fx(module, args, export_error):
    """torch.fx + make_fx: for modules torch.export cannot capture (symbolic tracing refuses data-
    dependent control flow too, so the ATen graph it yields is the one every input takes)."""
    from torch.fx.experimental.proxy_tensor import make_fx

    try:
        traced = torch.fx.symbolic_trace(module)
        gm = make_fx(traced, tracing_mode="fake")(*args)
    except Exception as exc:
        first = _classify(exc) or _classify(export_error)
        if first is not None:
            raise ConvertError(first) from None
        where = _user_frame(export_error.__traceback__)
        reason = str(export_error).strip().splitlines()[0][:200] if str(export_error).strip() else type(export_error).__name__
        raise ConvertError(f"{where + ': ' if where else ''}cannot capture the module's graph "
                           f"(torch.export: {reason}; torch.fx: {str(exc).strip().splitlines()[0][:120]})") from None
    consts, user = {}, []
    for node in gm.graph.nodes:
        if node.op == "placeholder":
            user.append(node.name)
        elif node.op == "get_attr":
            consts[node.name] = getattr(gm, node.target)
    return gm, consts, user


# --- lowering ----------------------------------------------------------------------------

def _op_name(target) -> str:
    """aten.sort.default -> 'sort'."""
    name = getattr(target, "__name__", str(target))
    if hasattr(target, "_schema"):
        name = target._schema.name.split("::")[-1]
    return name.split(".")[0]


def _where(node) -> str:
    """'file:line: module.path' of an FX node, as much as the trace recorded."""
    parts = []
    trace = node.meta.get("stack_trace") or ""
    files = [line.strip() for line in trace.splitlines() if line.strip().startswith("File ")]
    if files:
        last = files[-1]   # File "/x/model.py", line 42, in forward
        try:
            path = last.split('"')[1]
            lineno = last.split("line ")[1].split(",")[0]
            parts.append(f"{_short(path)}:{lineno}")
        except IndexError:
            pass
    stack = node.meta.get("nn_module_stack") or {}
    if stack:
        path = list(stack.values())[-1][0]
        if path:
            parts.append(path)
    return ": ".join(parts)


class TorchLowering:
    """Walks an ATen graph and drives a ``Lowering``."""

    def __init__(self, lowering: Lowering, consts: dict, batch: int):
        self.L, self.consts, self.batch = lowering, consts, batch

    def run(self, gm, user_inputs: list[str], input_specs: list[tuple[str, tuple, str]]):
        """``input_specs``: (port name, shape of one row, semantic[, batch axes]) per user input; an
        input of several batch axes was traced as [1, .., 1, TRACE_BATCH, *row]."""
        env = {}
        feeds = dict(zip(user_inputs, input_specs))
        outputs = None
        for node in gm.graph.nodes:
            if node.op == "placeholder":
                if node.name in feeds:
                    name, row, semantic, *lead = feeds[node.name]
                    lead = lead[0] if lead else 1
                    shape = [None] * lead + list(row) if lead > 1 else None
                    f = self.L.input(name, int(np.prod(row)), semantic, shape=shape)
                    env[node] = Feat(f.lanes.reshape((1,) * lead + tuple(row)), lead - 1)
                else:
                    env[node] = self.consts[node.name]
            elif node.op == "get_attr":
                env[node] = self.consts.get(node.name, getattr(gm, node.target, None))
            elif node.op == "call_function":
                env[node] = self._call(node, env)
            elif node.op == "output":
                outputs = torch.fx.node.map_arg(node.args[0], lambda n: env[n])
        return outputs

    def _call(self, node, env):
        args = torch.fx.node.map_arg(node.args, lambda n: env[n])
        kwargs = torch.fx.node.map_arg(node.kwargs, lambda n: env[n])
        name = _op_name(node.target)
        if node.target is operator.getitem:
            return args[0][args[1]]
        if not _has_feat((args, kwargs)):
            try:
                return node.target(*args, **kwargs)   # constants only: torch computes it
            except Exception as exc:
                raise ConvertError(f"{_where(node)}: torch.{name} on constants failed ({exc})") from None
        entry = TORCH_OPS.entry(name)
        where = _where(node)
        if entry is None:
            raise ConvertError(f"{where + ': ' if where else ''}torch.{name} has no shader lowering "
                               "(see inshade convert --ops)")
        try:
            if not entry.option("takes_ints"):   # an integer meets a float op: the float it was cast from
                args, kwargs = map_ints((args, kwargs), self.L.int_to_float)
            return entry.lower(self, node, *args, **kwargs)
        except ConvertError as exc:
            raise ConvertError(f"{where + ': ' if where else ''}torch.{name}: {exc}") from None

    # shapes from the trace: the batch axis is the one of TRACE_BATCH rows
    def out_shape(self, node) -> tuple[int, ...]:
        val = node.meta.get("val")
        if val is None or not hasattr(val, "shape"):
            raise ConvertError("the trace recorded no shape")
        return tuple(int(s) for s in val.shape)

    @staticmethod
    def array(c):
        """A constant as float32 numpy."""
        return floats(c)


def _has_feat(obj) -> bool:
    if isinstance(obj, (Feat, Condition)):
        return True
    if isinstance(obj, (list, tuple)):
        return any(_has_feat(o) for o in obj)
    if isinstance(obj, dict):
        return any(_has_feat(o) for o in obj.values())
    return False
