"""Write the environments' keyword and observation tables from their one declaration.

The keyword table comes from the :class:`~omni_gym.envs.config.EnvConfig` declarations
(:class:`~omni_gym.envs.config.Option`: default, kind, bound or choices, unit, meaning) and the
registered ids' own values (:data:`omni_gym.envs.ENV_IDS`); the observation tables from
:mod:`omni_gym.envs.observations`. The keyword table stands in the docstring of ``OmniPathEnv`` and in
``docs/environments.md``, the observation tables there and in ``OmniPathVectorEnv``'s docstring, the
bounds with their reasons (from the same declarations) in ``docs/bounds.md``::

    python -m omni_gym.envs.docgen --check   # exit 1 naming every stale file (tests/test_env_docs.py)
    python -m omni_gym.envs.docgen --write   # rewrite them

The docstrings are written into the source, not assembled at import: the source then reads as what
``help()`` shows, and a docstring stays plain text for every tool that reads it without importing.
Each table is located by the line before it (its anchor): the first Markdown table after the anchor
line is replaced, keeping its indentation; the text around it is not touched.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path

from omni_gym.envs import ENV_IDS
from omni_gym.envs.config import (
    MAX_OBSTACLES,
    MIN_OBSTACLE_RADIUS,
    OBS_MODES,
    OPTIONS,
    WHEEL_COUNT,
    EnvConfig,
    Option,
)
from omni_gym.envs.observations import build_layout
from omni_gym.physics.friction import FRICTION_MODELS, SURFACES
from omni_gym.physics.robot import PRESETS

ROOT = Path(__file__).resolve().parents[2]


def _value(v) -> str:
    """A keyword value as a table cell: names in backticks, numbers in short form."""
    if v is None or isinstance(v, bool):
        return str(v)
    if isinstance(v, str):
        return f"`{v}`"
    if isinstance(v, float):
        return f"{v:g}"
    return repr(v)


def short_id(env_id: str) -> str:
    """``OmniPathFollow-Phunopas-v0`` → ``Phunopas-v0``, ``OmniGoToPose-v0`` → ``GoToPose-v0``."""
    return env_id.removeprefix("OmniPathFollow-").removeprefix("Omni")


def default_cell(name: str) -> str:
    """The keyword's default, then each registered id that passes another value: ``20; GoToPose-v0: 8``."""
    default = getattr(EnvConfig(), name)
    by_value: dict[str, list[str]] = {}
    for env_id, (kwargs, _steps) in ENV_IDS.items():
        if name in kwargs and kwargs[name] != default:
            by_value.setdefault(_value(kwargs[name]), []).append(short_id(env_id))
    return "; ".join([_value(default)] + [f"{', '.join(ids)}: {v}" for v, ids in by_value.items()])


def allowed_cell(opt: Option) -> str:
    """The values the keyword accepts, as :func:`omni_gym.envs.config.make_config` checks them."""
    if opt.kind == "robot":
        text = ", ".join(f"`{p}`" for p in PRESETS) + f", `regularN` ({WHEEL_COUNT[0]} ≤ N ≤ {WHEEL_COUNT[1]})"
    elif opt.kind == "choice":
        text = ", ".join(_value(c) for c in opt.choices)
    elif opt.kind == "model":
        text = "None, a model JSON file path (str or `os.PathLike`), its dict, a `SimModel`"
    elif opt.kind == "flag":
        text = "True, False"
    elif opt.kind == "number":
        text = opt.bound().interval().replace(f"{math.pi:g}", "π")
    elif opt.kind == "range":
        text = f"None or (lo, hi) with {opt.lo:g} ≤ lo ≤ hi ≤ {opt.hi:g}"
    elif opt.kind == "floors":
        surfaces = "/".join(f"`{name}`" for name in SURFACES)
        models = "/".join(f"`{name}`" for name in FRICTION_MODELS)
        text = f"None or a non-empty tuple of {surfaces}, each optionally `:` {models}"
    elif opt.kind == "obstacles":
        text = f"at most {MAX_OBSTACLES} discs, radius ≥ {MIN_OBSTACLE_RADIUS:g}"
    elif opt.kind == "reward":
        text = "None, `BuiltinReward` (the built-in), a callable `f(RewardInputs) -> (B,) array`, or a class of such"
    else:
        raise ValueError(f"option {opt.name!r}: unknown kind {opt.kind!r}")
    return f"{text}; {opt.also}" if opt.also else text


def options_table() -> str:
    """Every ``gym.make`` keyword as a Markdown table, in declaration order."""
    lines = ["| keyword | default | allowed | unit | meaning |", "|---|---|---|---|---|"]
    for name, opt in OPTIONS.items():
        lines.append(_row([f"`{name}`", default_cell(name), allowed_cell(opt), opt.unit or "—", opt.doc], name))
    return "\n".join(lines)


def bounds_table() -> str:
    """The keywords with a bound and its reason, as the table of ``docs/bounds.md``."""
    lines = ["| keyword | unit | bounds | reason |", "|---|---|---|---|"]
    for name, opt in OPTIONS.items():
        if opt.reason:
            lines.append(_row([f"`{name}`", opt.unit or "—", allowed_cell(opt), opt.reason], name))
    return "\n".join(lines)


def _row(cells: list[str], name: str) -> str:
    if any("|" in c or "\\" in c for c in cells):  # a bar splits the row; a backslash breaks the docstrings
        raise ValueError(f"option {name!r}: no '|' or backslash in its table cells: {cells}")
    return "| " + " | ".join(cells) + " |"


@dataclass(frozen=True)
class Target:
    """One generated table: the file, the anchor line (a regular expression) and the table's text."""

    path: str
    anchor: str
    table: str


def targets() -> list[Target]:
    """Every generated table in every file that shows one."""
    obs = {mode: build_layout(mode, 3, 3).table() for mode in OBS_MODES}
    out = []
    keywords = {"omni_gym/envs/omni_env.py": r"\s*## Arguments$", "docs/environments.md": r"## Keyword arguments$"}
    for path in ("omni_gym/envs/omni_env.py", "omni_gym/envs/vector.py", "docs/environments.md"):
        if path in keywords:  # the vector docstring refers to OmniPathEnv's table for the keywords
            out.append(Target(path, keywords[path], options_table()))
        for mode in OBS_MODES:
            out.append(Target(path, rf'\s*`{{1,2}}obs_mode="{mode}"`{{1,2}} \(', obs[mode]))
    out.append(Target("docs/bounds.md", r"## Environment keywords", bounds_table()))
    return out


def replace_table(text: str, anchor: str, table: str, where: str = "") -> str:
    """``text`` with the first Markdown table after the (unique) line matching ``anchor`` replaced by
    ``table``, indented as the table it replaces. ValueError if the anchor or the table is missing."""
    lines = text.split("\n")
    hits = [i for i, line in enumerate(lines) if re.match(anchor, line)]
    if len(hits) != 1:
        raise ValueError(f"{where}: {len(hits)} lines match the anchor {anchor!r}; need exactly one")
    start = next((i for i in range(hits[0] + 1, len(lines)) if lines[i].lstrip().startswith("|")), None)
    if start is None:
        raise ValueError(f"{where}: no table after the anchor {anchor!r}")
    end = start
    while end < len(lines) and lines[end].lstrip().startswith("|"):
        end += 1
    indent = lines[start][:len(lines[start]) - len(lines[start].lstrip())]
    return "\n".join(lines[:start] + [indent + row for row in table.split("\n")] + lines[end:])


def rendered(root: Path = ROOT) -> dict[str, tuple[str, str]]:
    """File (relative path) → (its text now, its text with every generated table current)."""
    out: dict[str, tuple[str, str]] = {}
    for t in targets():
        if t.path not in out:
            text = (root / t.path).read_text(encoding="utf-8")
            out[t.path] = (text, text)
        now, new = out[t.path]
        out[t.path] = (now, replace_table(new, t.anchor, t.table, t.path))
    return out


def stale(root: Path = ROOT) -> list[str]:
    """The files whose generated tables differ from the declarations."""
    return [path for path, (now, new) in rendered(root).items() if now != new]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m omni_gym.envs.docgen", description=__doc__.split("\n")[0])
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true", help="exit 1 if a generated table is stale")
    mode.add_argument("--write", action="store_true", help="rewrite the stale files")
    args = parser.parse_args(argv)
    files = rendered()
    old = [path for path, (now, new) in files.items() if now != new]
    if args.write:
        for path in old:
            (ROOT / path).write_text(files[path][1], encoding="utf-8")
        print("rewrote " + ", ".join(old) if old else "every generated table is current")
        return 0
    for path in old:
        print(f"{path}: generated tables are stale; run python -m omni_gym.envs.docgen --write", file=sys.stderr)
    return 1 if old else 0


if __name__ == "__main__":
    sys.exit(main())
