"""What ``evaluate --policy SPEC`` (and ``--against``) may name, and how each kind is built: a loader chain.

Each loader says whether it takes a spec (:meth:`PolicyLoader.accepts`, from the spec alone: a name or
what is on disk) and builds ``(env, policy)`` for it (:meth:`PolicyLoader.load`). :data:`LOADERS` is asked
in order; the first that accepts builds. The order matters where two could take the same folder: an
RLlib model directory and a gated controller also hold a ``meta.json``, so their loaders come before SB3's model
directory.

=================  =================================================================  ==========================
loader             accepts                                                            builds with
=================  =================================================================  ==========================
scripted           a name of :data:`agents.policies.POLICIES`                          :func:`make_policy`
recommended        the name ``recommended``: per id, a gated controller or ekf-pid      :mod:`agents.recommended`
rllib              our ``--backend rllib`` directory or a bare RLlib checkpoint        :mod:`agents.rllib.policy`
gated              a gated controller's directory (``meta.json`` with kind "gated")    :mod:`agents.gated`
sb3-model          our model directory (``meta.json`` + model zip)                    :mod:`agents.sb3_policy`
rl-zoo             any other directory (an RL Zoo output folder)                      :mod:`agents.sb3_policy`
sb3-zip            a path ending in ``.zip`` (a plain SB3 model; it may not exist:    :mod:`agents.sb3_policy`
                   the SB3 loader then says so)
=================  =================================================================  ==========================

A spec no loader accepts gets one line (:func:`find_loader`): a file that is not a model, a path that
does not exist, or an unknown policy name with the names to choose from.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from agents.gated import build as build_gated
from agents.gated import is_gated
from agents.policies import POLICIES, make_policy
from agents.recommended import NAME as RECOMMENDED
from agents.recommended import resolve as resolve_recommended
from agents.rllib.policy import build as build_rllib
from agents.rllib.policy import is_rllib_model
from agents.rollout import make_env
from agents.sb3_policy import META, ModelOptions, build


class PolicyLoader(Protocol):
    """One kind of ``--policy``: whether a spec is of this kind, and the (env, policy) it builds."""

    name: str

    def accepts(self, spec: str) -> bool:
        """True if this loader builds ``spec`` (decided from the name and what is on disk, nothing loaded)."""

    def check_options(self, spec: str, options: ModelOptions | None) -> None:
        """ValueError (one line) if ``options`` (the command line's model options) do not apply to ``spec``."""

    def load(self, spec: str, env_id: str, env_kwargs: dict | None, options: ModelOptions | None):
        """``(env, policy)``: the environment built as the policy needs it, and the policy acting on it."""


def _given(options: ModelOptions | None) -> list[str]:
    return [] if options is None else options.given()


@dataclass(frozen=True)
class ScriptedLoader:
    """A scripted policy by name; the environment as ``env_kwargs`` say (sensors and twist by default)."""

    name: str = "scripted"

    def accepts(self, spec: str) -> bool:
        return spec in POLICIES

    def check_options(self, spec: str, options: ModelOptions | None) -> None:
        if _given(options):
            raise ValueError(f"{_given(options)[0]} applies to a trained model, not to the scripted policy {spec!r}")

    def load(self, spec: str, env_id: str, env_kwargs: dict | None, options: ModelOptions | None):
        env = make_env(env_id, env_kwargs)
        try:
            return env, make_policy(spec, env)
        except BaseException:
            env.close()
            raise


@dataclass(frozen=True)
class RLlibLoader:
    """An RLlib model (:mod:`agents.rllib.policy`): no SB3 option applies."""

    name: str = "rllib"

    def accepts(self, spec: str) -> bool:
        return is_rllib_model(spec)

    def check_options(self, spec: str, options: ModelOptions | None) -> None:
        if _given(options):
            raise ValueError(f"{_given(options)[0]} applies to an SB3 model, not to the RLlib model {spec}")

    def load(self, spec: str, env_id: str, env_kwargs: dict | None, options: ModelOptions | None):
        return build_rllib(spec, env_id, env_kwargs, trust_pickle=options is not None and options.trust_pickle)


@dataclass(frozen=True)
class RecommendedLoader:
    """``recommended``: the controller :func:`agents.recommended.resolve` names for the id, built by its loader."""

    name: str = "recommended"

    def accepts(self, spec: str) -> bool:
        return spec == RECOMMENDED

    def check_options(self, spec: str, options: ModelOptions | None) -> None:
        if _given(options):
            raise ValueError(f"{_given(options)[0]} applies to a trained model, not to 'recommended'")

    def load(self, spec: str, env_id: str, env_kwargs: dict | None, options: ModelOptions | None):
        target = resolve_recommended(env_id)
        return find_loader(target).load(target, env_id, env_kwargs, options)


@dataclass(frozen=True)
class GatedLoader:
    """A gated controller (:mod:`agents.gated`): ekf-pid, then its student; the model options apply to the
    student."""

    name: str = "gated"

    def accepts(self, spec: str) -> bool:
        return is_gated(spec)

    def check_options(self, spec: str, options: ModelOptions | None) -> None:
        """Nothing here: the options are the student's, checked when it loads."""

    def load(self, spec: str, env_id: str, env_kwargs: dict | None, options: ModelOptions | None):
        return build_gated(spec, env_id, env_kwargs, options)


@dataclass(frozen=True)
class SB3Loader:
    """An SB3 model of one ``kind`` ("sb3-model", "rl-zoo" or "sb3-zip"; :func:`agents.sb3_policy.resolve`
    reads each); the model options are checked against its files there."""

    name: str

    def accepts(self, spec: str) -> bool:
        p = Path(spec)
        if self.name == "sb3-model":
            return p.is_dir() and (p / META).is_file()
        if self.name == "rl-zoo":
            return p.is_dir() and not (p / META).is_file()
        return spec.endswith(".zip")

    def check_options(self, spec: str, options: ModelOptions | None) -> None:
        """Nothing here: which options apply depends on the model's files (checked when it loads)."""

    def load(self, spec: str, env_id: str, env_kwargs: dict | None, options: ModelOptions | None):
        return build(spec, env_id, env_kwargs, options)


LOADERS: tuple[PolicyLoader, ...] = (ScriptedLoader(), RecommendedLoader(), RLlibLoader(), GatedLoader(),
                                     SB3Loader("sb3-model"), SB3Loader("rl-zoo"), SB3Loader("sb3-zip"))


def find_loader(spec: str) -> PolicyLoader:
    """The first loader of :data:`LOADERS` that accepts ``spec``; else ValueError, one line saying what it is not."""
    for loader in LOADERS:
        if loader.accepts(spec):
            return loader
    if os.path.exists(spec):
        raise ValueError(f"policy {spec!r}: not a model (a model directory, an RL Zoo folder or an SB3 .zip)")
    if os.sep in spec or "/" in spec or spec.startswith("."):
        raise ValueError(f"policy {spec!r}: no such folder or file (a model directory, an RL Zoo folder, an "
                         f"SB3 .zip or an RLlib checkpoint)")
    raise ValueError(f"{POLICIES.unknown(spec)}, '{RECOMMENDED}' or a saved model path (no such folder or file "
                     "either)")
