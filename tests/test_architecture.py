"""The package's imports layer without circles.

Every module of ``omni_gym/`` and ``agents/`` is parsed with ``ast``; every import counts, at module
level and inside functions (a function-level import runs too, it only runs later), relative imports
resolved. ``from pkg import name`` is an edge to the module ``pkg.name`` when it is one, else to ``pkg``.
Imports in the body of ``if TYPE_CHECKING:`` count too: they never run, but a type named across layers
or around a circle ties the modules together all the same (the effects type the model they read by a
narrow protocol of their own, ``omni_gym.physics.effects.base.ModelView``, not by importing it).

Layers (a module belongs to the longest prefix in :data:`LAYERS` that names it), bottom up:

* utilities: ``omni_gym.checks``, ``omni_gym.angles``, ``omni_gym.bounds``, ``omni_gym.io``,
  ``omni_gym.outputs`` (argument checks, the angle wrap, input bounds, file reading, atomic writing), on
  nothing else of the package;
* ``omni_gym.physics``: robot, model, kernel, world, replay, ..., on the utilities only;
* ``omni_gym.analysis``: the validation integrator and the max-force analysis, on the physics;
* core: the other ``omni_gym`` modules (sensors, trajectories, the package ``__init__``), on the physics;
* ``omni_gym.envs``: the Gymnasium environments, on core;
* ``omni_gym.rllib``: the ids registered with Ray's registry, on the environments (no agents);
* ``omni_gym.discrepancy``: the ``gap``/``synth`` workflow, on core only (no environments, no agents);
* ``agents``: baselines and SB3 training, on core and the environments (not the discrepancy workflow);
* ``omni_gym.cli``: the command line, on top of everything.

A new layer is one entry in :data:`LAYERS` (and its name in :data:`CORE` when core may import it).

Inside ``omni_gym.discrepancy`` the sub-packages are the stages of ``gap`` in the order the data flows
(:data:`STAGES`): a module imports its own stage and earlier ones, never a later one, so the folders read
in order (data in, replay, fit, decide, report; the workflow walks them; the synthetic test bench runs it).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("omni_gym", "agents")
UTILITIES = {"omni_gym.checks", "omni_gym.angles", "omni_gym.bounds", "omni_gym.io", "omni_gym.outputs"}
PHYSICS = UTILITIES | {"omni_gym.physics"}
CORE = PHYSICS | {"omni_gym"}
# layer (module-name prefix) -> the layers its modules may import (their own included)
LAYERS: dict[str, set[str] | None] = {
    **{u: UTILITIES for u in UTILITIES},
    "omni_gym.physics": PHYSICS,
    "omni_gym.analysis": PHYSICS | {"omni_gym.analysis"},
    "omni_gym": CORE,
    "omni_gym.envs": CORE | {"omni_gym.envs"},
    "omni_gym.rllib": CORE | {"omni_gym.envs", "omni_gym.rllib"},
    "omni_gym.discrepancy": CORE | {"omni_gym.discrepancy"},
    "agents": CORE | {"omni_gym.envs", "omni_gym.rllib", "agents"},
    "omni_gym.cli": None,  # on top: imports anything
}
# (importer, imported) pairs allowed against the layers, with the reason.
ALLOWED_UP = {
    # Importing omni_gym registers the environment ids with Gymnasium (gym.make("OmniGoToPose-v0")
    # works after `import omni_gym`); the package module re-exports, it is not a core module.
    ("omni_gym", "omni_gym.envs"),
    # Data made by an independent implementation: the validation integrator generates
    # test datasets for the workflow. Only this generator may use it; the workflow itself never does,
    # so the integrator stays independent of what it checks.
    ("omni_gym.discrepancy.synthetic.reference_data", "omni_gym.analysis"),
}


# The discrepancy workflow's parts, first to last (docs/architecture.md): a module may import only its own
# part and earlier ones. The settings come first: every stage reads its own, and they import no stage.
STAGES = tuple(f"omni_gym.discrepancy.{part}" for part in (
    "settings", "data", "replay", "fit", "decide", "report", "workflow", "synthetic"))


def _modules() -> dict[str, tuple[Path, bool]]:
    """Dotted module name -> (file, is a package ``__init__``)."""
    out = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            is_pkg = parts[-1] == "__init__"
            out[".".join(parts[:-1] if is_pkg else parts)] = (path, is_pkg)
    return out


def _known(name: str, modules: dict) -> str | None:
    """The longest prefix of ``name`` that is one of ``modules`` (None: outside the packages)."""
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def import_graph() -> dict[str, set[str]]:
    """Module -> the package modules it imports (anywhere in its body)."""
    modules = _modules()
    graph = {}
    for mod, (path, is_pkg) in modules.items():
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                targets |= {_known(a.name, modules) for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:  # relative: from the package of this module, level - 1 packages up
                    pkg = mod.split(".") if is_pkg else mod.split(".")[:-1]
                    pkg = pkg[:len(pkg) - (node.level - 1)]
                    base = ".".join(pkg + ([base] if base else []))
                for alias in node.names:
                    sub = f"{base}.{alias.name}"
                    targets.add(sub if sub in modules else _known(base, modules))
        graph[mod] = {t for t in targets if t is not None and t != mod}
    return graph


def layer(mod: str) -> str:
    """The layer of module ``mod``: the longest matching prefix in :data:`LAYERS`."""
    return max((k for k in LAYERS if mod == k or mod.startswith(k + ".")), key=len)


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle as [a, b, ..., a], or None (depth-first search with colours)."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(m: str) -> list[str] | None:
        state[m] = 1
        path.append(m)
        for n in sorted(graph.get(m, ())):
            if state.get(n) == 1:
                return path[path.index(n):] + [n]
            if n not in state and (found := visit(n)):
                return found
        path.pop()
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state and (found := visit(m)):
            return found
    return None


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    """Every import from a module to a layer its own layer may not import, except :data:`ALLOWED_UP`."""
    bad = []
    for mod, targets in sorted(graph.items()):
        allowed = LAYERS[layer(mod)]
        for t in sorted(targets):
            if allowed is not None and layer(t) not in allowed and (mod, layer(t)) not in ALLOWED_UP:
                bad.append(f"{mod} ({layer(mod)}) imports {t} ({layer(t)})")
    return bad


def stage(mod: str) -> int | None:
    """Index in :data:`STAGES` of the part that holds ``mod`` (None: outside them, e.g. the package ``__init__``)."""
    found = [i for i, s in enumerate(STAGES) if mod == s or mod.startswith(s + ".")]
    return found[0] if found else None


def later_stage_imports(graph: dict[str, set[str]]) -> list[str]:
    """Every import from a discrepancy module to a later stage than its own."""
    bad = []
    for mod, targets in sorted(graph.items()):
        own = stage(mod)
        for t in sorted(targets):
            if own is not None and (other := stage(t)) is not None and other > own:
                bad.append(f"{mod} ({STAGES[own]}) imports {t} ({STAGES[other]}), a later stage")
    return bad


def test_no_import_cycle():
    assert find_cycle(import_graph()) is None, " -> ".join(find_cycle(import_graph()))


def test_no_import_points_up_the_layers():
    assert upward_imports(import_graph()) == []


def test_every_allowed_exception_is_still_needed():
    """A stale allow-list entry would hide a future upward import of the same pair."""
    graph = import_graph()
    used = {(m, layer(t)) for m, ts in graph.items() for t in ts}
    assert ALLOWED_UP <= used


def test_the_checks_catch_a_cycle_and_an_upward_import():
    """The checkers on made-up graphs: a cycle through a function-level import, and core importing agents."""
    assert find_cycle({"a.x": {"a.y"}, "a.y": {"a.z"}, "a.z": {"a.x"}}) == ["a.x", "a.y", "a.z", "a.x"]
    assert find_cycle({"a.x": {"a.y"}, "a.y": set()}) is None
    assert upward_imports({"omni_gym.physics.model": {"agents.train"}}) == [
        "omni_gym.physics.model (omni_gym.physics) imports agents.train (agents)"]
    assert upward_imports({"omni_gym.physics.world": {"omni_gym.sensors"}})  # physics below core
    assert upward_imports({"omni_gym.bounds": {"omni_gym.physics.liftoff"}})  # utilities below physics
    assert upward_imports({"omni_gym.discrepancy.synthetic.synth": {"omni_gym.analysis.reference"}})
    assert upward_imports({"omni_gym.discrepancy.synthetic.synth": {"omni_gym.envs.core"}})
    assert upward_imports({"agents.train": {"omni_gym.discrepancy.synthetic.synth"}})
    assert upward_imports({"agents.train": {"omni_gym.cli"}})
    assert upward_imports({"omni_gym.cli": {"agents.train", "omni_gym.discrepancy.synthetic.synth"}}) == []


def test_the_discrepancy_stages_import_only_earlier_stages():
    assert later_stage_imports(import_graph()) == []


def test_every_discrepancy_module_sits_in_a_stage():
    """A module added beside the stages would escape the order check: only the package itself may."""
    loose = [m for m in _modules() if m.startswith("omni_gym.discrepancy") and stage(m) is None]
    assert loose == ["omni_gym.discrepancy"]


def test_the_stage_check_catches_an_import_of_a_later_stage():
    """On made-up graphs: fit importing decide, data importing replay, a stage importing the workflow."""
    fit_to_decide = {"omni_gym.discrepancy.fit.events": {"omni_gym.discrepancy.decide.decision"}}
    assert later_stage_imports(fit_to_decide) == [
        "omni_gym.discrepancy.fit.events (omni_gym.discrepancy.fit) imports omni_gym.discrepancy.decide.decision "
        "(omni_gym.discrepancy.decide), a later stage"]
    assert later_stage_imports({"omni_gym.discrepancy.data.segments": {"omni_gym.discrepancy.replay.localise"}})
    assert later_stage_imports({"omni_gym.discrepancy.report.report": {"omni_gym.discrepancy.workflow"}})
    assert later_stage_imports({"omni_gym.discrepancy.workflow": {"omni_gym.discrepancy.synthetic.synth"}})
    assert later_stage_imports({"omni_gym.discrepancy.settings": {"omni_gym.discrepancy.data.dataset"}})
    assert later_stage_imports({  # earlier stages, the own stage and modules outside the stages are fine
        "omni_gym.discrepancy.decide.decision": {"omni_gym.discrepancy.fit.candidates",
                                                 "omni_gym.discrepancy.settings"},
        "omni_gym.discrepancy.fit.fitting": {"omni_gym.discrepancy.fit.search", "omni_gym.physics.world"},
        "omni_gym.discrepancy.synthetic.recovery": {"omni_gym.discrepancy.workflow"},
        "omni_gym.cli": {"omni_gym.discrepancy.synthetic.synth"}}) == []


@pytest.mark.parametrize("source, expect", [
    ("from . import b\n", "p.b"),  # relative, from a module of package p
    ("from .b import f\n", "p.b"),
    ("def g():\n    from p.b import f\n", "p.b"),  # function level
    ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from p.b import f\n", "p.b"),  # type only
])
def test_the_parser_resolves_relative_function_level_and_type_only_imports(tmp_path, monkeypatch, source, expect):
    (tmp_path / "p").mkdir()
    (tmp_path / "p" / "__init__.py").write_text("")
    (tmp_path / "p" / "a.py").write_text(source)
    (tmp_path / "p" / "b.py").write_text("def f():\n    pass\n")
    monkeypatch.setitem(globals(), "ROOT", tmp_path)
    monkeypatch.setitem(globals(), "PACKAGES", ("p",))
    assert import_graph()["p.a"] == {expect}


def test_the_package_reexports_load_on_first_use_and_are_the_physics_objects():
    """`import omni_gym` loads neither the world nor numba (import stays light); the re-exported
    names are the very objects of their physics modules."""
    import subprocess
    import sys

    code = ("import sys, omni_gym; print(sorted(m for m in ('omni_gym.physics.world', 'omni_gym.physics.kernel', "
            "'numba', 'pymunk') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert out.stdout.strip() == "[]"
    import importlib

    import omni_gym
    for name, module in omni_gym._EXPORTS.items():
        assert getattr(omni_gym, name) is getattr(importlib.import_module(module), name)
        assert name in omni_gym.__all__
