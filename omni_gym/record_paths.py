"""Paths as committed records write them: relative to the repository, never a machine's absolute path.

A ``meta.json`` command or a results header that says ``--out /work/main/agents/models/x`` or ``--cache
/tmp/ns_cache.json`` names a folder on the machine that made it, which nobody else has. :func:`record_path`
writes a path inside the repository relative to its root and any other path by its name only;
:func:`record_args` does so for every absolute path in a command's arguments (``--out PATH`` and
``--out=PATH`` alike).
"""

from __future__ import annotations

import os
import shlex
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]  # the repository root (the folder holding omni_gym/)


def record_path(path: str | os.PathLike) -> str:
    """``path`` relative to the repository root when it lies inside it, else its name only; a relative path is
    kept as given (it already names no machine)."""
    text = os.fspath(path)
    p = Path(text)
    if not p.is_absolute():
        return text
    try:
        return p.resolve().relative_to(ROOT).as_posix() or "."
    except ValueError:
        return p.name or text


def record_args(args: list[str]) -> list[str]:
    """``args`` with every absolute path (a whole argument, or the value of ``--opt=PATH``) through
    :func:`record_path`."""
    out = []
    for a in args:
        opt, eq, value = a.partition("=")
        if eq and opt.startswith("-") and os.path.isabs(value):
            out.append(f"{opt}={record_path(value)}")
        else:
            out.append(record_path(a) if os.path.isabs(a) else a)
    return out


def record_command(prefix: str, args: list[str]) -> str:
    """``prefix`` followed by ``args`` (shell-quoted), absolute paths recorded by :func:`record_args`."""
    return " ".join([prefix, *(shlex.quote(a) for a in record_args(list(args)))]).rstrip()
