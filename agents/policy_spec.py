"""``policy_kwargs`` as data: layer sizes, numbers and the *names* of a few known classes, never code.

A hyperparameter file (and a model's ``meta.json``) describes the policy network declaratively::

    policy_kwargs: {net_arch: {pi: [64, 64], vf: [64, 64]}, activation_fn: Tanh, log_std_init: -1.5}

The RL Zoo's string form (``"dict(net_arch=[64, 64], activation_fn=nn.Tanh)"``) is also read: it is
*parsed* (``dict(...)`` calls with keyword arguments, literals, and the dotted names of the classes
below), never evaluated. :func:`declarative` gives the JSON form of either; :func:`to_sb3` turns it into
the keyword arguments stable-baselines3 takes (each class name looked up in a fixed table).
"""

from __future__ import annotations

import ast
import importlib

# name -> "module:attribute" (imported on use; torch is heavy). Only these classes can be named.
ACTIVATIONS = {name: f"torch.nn:{name}" for name in
               ("Tanh", "ReLU", "ELU", "LeakyReLU", "GELU", "SiLU", "Sigmoid", "Softplus", "Identity")}
EXTRACTORS = {"FlattenExtractor": "stable_baselines3.common.torch_layers:FlattenExtractor",
              "AffineSkip": "agents.networks:AffineSkip"}
OPTIMIZERS = {name: f"torch.optim:{name}" for name in ("Adam", "AdamW", "SGD", "RMSprop")}
CLASS_KEYS = {"activation_fn": ACTIVATIONS, "features_extractor_class": EXTRACTORS, "optimizer_class": OPTIMIZERS}
# keys of SB3's MLP policies (PPO/A2C ActorCriticPolicy, SACPolicy, TD3Policy) whose values are data
DATA_KEYS = {"net_arch", "log_std_init", "ortho_init", "use_sde", "squash_output", "full_std", "use_expln",
             "clip_mean", "n_critics", "share_features_extractor", "features_extractor_kwargs",
             "optimizer_kwargs", "normalize_images"}
MAX_ITEMS = 64  # per list or mapping: a policy description is small
MAX_DEPTH = 4


def _short(text) -> str:
    s = " ".join(str(text).split())
    return s if len(s) <= 80 else s[:77] + "..."


def _check_value(value, where: str, depth: int = 0):
    """``value`` if it is plain data (numbers, bools, None, short strings, small lists and mappings)."""
    if depth > MAX_DEPTH:
        raise ValueError(f"{where}: nested more than {MAX_DEPTH} levels")
    if value is None or isinstance(value, (bool, int, float)):
        return value
    if isinstance(value, str) and len(value) <= 64:
        return value
    if isinstance(value, (list, tuple)) and len(value) <= MAX_ITEMS:
        return [_check_value(v, where, depth + 1) for v in value]
    if isinstance(value, dict) and len(value) <= MAX_ITEMS and all(isinstance(k, str) for k in value):
        return {k: _check_value(v, f"{where}.{k}", depth + 1) for k, v in value.items()}
    raise ValueError(f"{where}: {_short(value)!r} is not plain data (numbers, names, lists, mappings)")


def _class_name(key: str, value, where: str) -> str:
    table = CLASS_KEYS[key]
    name = value.rpartition(".")[2] if isinstance(value, str) else getattr(value, "__name__", None)
    if name not in table:
        raise ValueError(f"{where}: key {key!r}: {_short(value)!r} is not one of {', '.join(table)}")
    return name


def _check_mapping(value: dict, where: str) -> dict:
    out = {}
    for key, v in value.items():
        if key in CLASS_KEYS:
            out[key] = _class_name(key, v, where)
        elif key in DATA_KEYS:
            out[key] = _check_value(v, f"{where}: key {key!r}")
        else:
            raise ValueError(f"{where}: policy_kwargs key {_short(key)!r} is not known (known: "
                             f"{', '.join(sorted(DATA_KEYS | set(CLASS_KEYS)))})")
    return out


def _node(node: ast.AST, where: str, depth: int = 0):
    """The data an RL Zoo expression node stands for (dict calls, literals, dotted class names)."""
    if depth > MAX_DEPTH + 2:
        raise ValueError(f"{where}: policy_kwargs nested too deeply")
    if isinstance(node, ast.Constant) and (node.value is None or isinstance(node.value, (bool, int, float, str))):
        return node.value
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub) and isinstance(node.operand, ast.Constant) \
            and isinstance(node.operand.value, (int, float)) and not isinstance(node.operand.value, bool):
        return -node.operand.value
    if isinstance(node, (ast.List, ast.Tuple)):
        return [_node(e, where, depth + 1) for e in node.elts]
    if isinstance(node, ast.Dict) and all(isinstance(k, ast.Constant) and isinstance(k.value, str) for k in node.keys):
        return {k.value: _node(v, where, depth + 1) for k, v in zip(node.keys, node.values, strict=True)}
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict" and not node.args \
            and all(kw.arg is not None for kw in node.keywords):
        return {kw.arg: _node(kw.value, where, depth + 1) for kw in node.keywords}
    if isinstance(node, (ast.Name, ast.Attribute)):  # nn.Tanh, th.nn.ReLU, AffineSkip: a class *name*
        parts = []
        while isinstance(node, ast.Attribute):
            parts.append(node.attr)
            node = node.value
        if isinstance(node, ast.Name):
            return ".".join([node.id, *reversed(parts)])
    raise ValueError(f"{where}: policy_kwargs: {_short(ast.unparse(node))!r} is not allowed (dict(...), numbers, "
                     f"lists and class names such as nn.Tanh)")


def declarative(value, where: str) -> dict:
    """The JSON form of a ``policy_kwargs`` value (None, a mapping, or an RL Zoo string); ValueError naming
    ``where`` for anything but layer sizes, numbers and known class names."""
    if value is None:
        return {}
    if isinstance(value, str):
        if len(value) > 2000:
            raise ValueError(f"{where}: policy_kwargs is {len(value)} characters long (at most 2000)")
        try:
            tree = ast.parse(value, mode="eval")
        except SyntaxError as exc:
            raise ValueError(f"{where}: policy_kwargs {_short(value)!r}: not an expression ({exc.msg})") from None
        value = _node(tree.body, where)
    if not isinstance(value, dict):
        raise ValueError(f"{where}: policy_kwargs must be a mapping, got {_short(value)!r}")
    return _check_mapping(value, where)


def _import(path: str):
    module, _, attr = path.partition(":")
    return getattr(importlib.import_module(module), attr)


def to_sb3(decl: dict) -> dict:
    """The stable-baselines3 ``policy_kwargs`` of a declarative description (class names -> the classes)."""
    out = dict(decl)
    for key, table in CLASS_KEYS.items():
        if key in out:
            out[key] = _import(table[out[key]])
    if isinstance(out.get("net_arch"), dict):  # JSON has no tuples; SB3 wants lists, which JSON gives
        out["net_arch"] = dict(out["net_arch"])
    return out
