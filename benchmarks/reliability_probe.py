"""Reliability probe: bad inputs on the command line, each in a fresh ``omni-gym`` process.

    python benchmarks/reliability_probe.py [--jobs 2] [--out benchmarks/results] [--only CATEGORY]

Every case is an input a user could give by mistake or an attacker on purpose: malformed and absurd
files (commands CSV, model JSON, dataset, OptiOdom logs, CSV logs, ROS 2 bags, hyperparameter YAML), special
files (``/dev/zero``, a pipe), oversized inputs, crafted models (pickles with a payload, ``meta.json`` paths
leading out of the folder), bad options of every subcommand, unit mistakes. A case is **clean** when the process
exits with status 2 and prints exactly one line ``omni-gym: error: ...`` (no traceback), its peak resident memory
stays under 1 GB and it ends within the case's time limit (argparse's refusal of a malformed option, its usage
line then ``omni-gym COMMAND: error: ...``, counts as clean too); a crafted model must also leave its payload's
marker file absent. Each process runs in an empty working folder, which must stay empty, and a refused command
must leave no ``--out`` behind. A few cases are good inputs that must be accepted (``expect="ok"``, e.g. a CSV log
with a byte-order mark and CRLF line ends): exit 0 counts as ``ok as expected``, a refusal as ``refused``.
Anything else is counted by kind: ``accepted`` (exit 0: the bad input was not refused, a silent accept),
``traceback``, ``other status`` (also a warning printed before the error line), ``memory``, ``hang``, ``code ran``,
``wrote`` (a file outside ``--out``, in the working folder, a refused command's ``--out``, or ``--force`` replaced a
FIFO) and ``unescaped`` (a control character, e.g. an escape sequence from a crafted file, reached the terminal).

The builders and their categories are :data:`CATEGORIES`; ``--only TEXT`` builds and runs just the categories whose
name contains TEXT (``--only hostile``: the hostile-input cases, in about half a minute).

The tables (counts per category and per subcommand, by kind, then every case that was not clean) go to ``--out``
(a file, or a folder: ``reliability_probe.md`` in it), headed by the exact command that produced them.
"""

from __future__ import annotations

import argparse
import base64
import gzip
import json
import os
import pickle
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import zipfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MEMORY_LIMIT_KB = 1024 * 1024  # 1 GB
TIME_LIMIT_S = 120.0  # per case; a refusal takes a few seconds (imports), a hang is stopped here


@dataclass
class Case:
    category: str
    name: str
    argv: list[str]
    marker: Path | None = None  # a crafted file's payload would create it
    result: dict = field(default_factory=dict)
    outside: Path | None = None  # a file the command must not write (a run name that is a path out of --out)
    fifo: Path | None = None  # a FIFO that --force must leave a FIFO
    env: dict = field(default_factory=dict)  # extra environment variables of the process
    time_limit: float | None = None  # seconds, when shorter than TIME_LIMIT_S (a refusal that must be quick)
    expect: str = "refuse"  # "ok": a good input that must be accepted (exit 0), e.g. a CSV with a byte-order mark


class _Marker:
    def __init__(self, path: str) -> None:
        self.path = path

    def __reduce__(self):
        return (open, (self.path, "w"))


def _payload(marker: Path) -> bytes:
    return pickle.dumps(_Marker(str(marker)))


def _bad_numbers() -> dict[str, object]:
    """Values no physical input accepts, by name (JSON values)."""
    return {"neg": -1.0, "zero": 0, "huge": 1e308, "tiny": 1e-308, "string": "x", "null": None, "true": True,
            "list": [], "object": {}, "digits": int("9" * 400), "negzero-int": -5}


def build_cases(work: Path) -> list[Case]:
    cases: list[Case] = []
    add = cases.append
    py = str(work)

    # --- commands CSV (simulate) -----------------------------------------------------------------
    good = "t,w1,w2,w3\n0,1,1,1\n0.1,1,1,1\n0.2,0,0,0\n"
    csvs = {
        "empty": "", "header only": "t,w1,w2,w3\n", "wrong header": "time,a,b,c\n0,1,1,1\n",
        "two wheels": "t,w1,w2\n0,1,1\n0.1,1,1\n", "five wheels": "t,w1,w2,w3,w4,w5\n0,1,1,1,1,1\n",
        "nan": "t,w1,w2,w3\n0,nan,1,1\n0.1,1,1,1\n", "inf": "t,w1,w2,w3\n0,inf,1,1\n0.1,1,1,1\n",
        "huge speed": "t,w1,w2,w3\n0,1e308,1,1\n0.1,1,1,1\n", "digits": "t,w1,w2,w3\n0," + "9" * 5000 + ",1,1\n",
        "negative time": "t,w1,w2,w3\n-1,1,1,1\n0,1,1,1\n", "not increasing": "t,w1,w2,w3\n0,1,1,1\n0,1,1,1\n",
        "first time not 0": "t,w1,w2,w3\n0.5,1,1,1\n1,1,1,1\n", "semicolons": "t;w1;w2;w3\n0;1;1;1\n",
        "tabs": "t\tw1\tw2\tw3\n0\t1\t1\t1\n", "text cell": "t,w1,w2,w3\n0,abc,1,1\n0.1,1,1,1\n",
        "underscore": "t,w1,w2,w3\n0,1_000,1,1\n0.1,1,1,1\n", "hex": "t,w1,w2,w3\n0,0x10,1,1\n0.1,1,1,1\n",
        "short row": "t,w1,w2,w3\n0,1,1\n", "long row": "t,w1,w2,w3\n0,1,1,1,1\n",
        "very long run": "t,w1,w2,w3\n0,1,1,1\n1e9,1,1,1\n", "quote": 't,w1,w2,w3\n0,"1,1,1\n',
        "nul bytes": "t,w1,w2,w3\n0,1\x00,1,1\n",
        "time digits": "t,w1,w2,w3\n0,1,1,1\n" + "1" * 400 + ",1,1,1\n", "blank cells": "t,w1,w2,w3\n0,,,\n",
        "header only with blank lines": "t,w1,w2,w3\n\n\n",
    }
    for name, text in csvs.items():
        f = work / f"cmd-{len(cases)}.csv"
        f.write_text(text)
        add(Case("commands CSV", name, ["simulate", "--model", "williams2002", "--commands", str(f), "--out",
                                        f"{py}/traj-{len(cases)}.csv"]))
    raw = {"latin-1": "t,w1,w2,w3\n0,\xe9,1,1\n".encode("latin-1"), "utf-16 no bom": good.encode("utf-16-le"),
           "random bytes": bytes(range(256)) * 8, "gzip garbage": b"\x1f\x8b" + b"\x00" * 40}
    for name, data in raw.items():
        f = work / f"cmd-{len(cases)}.csv" if "gzip" not in name else work / f"cmd-{len(cases)}.csv.gz"
        f.write_bytes(data)
        add(Case("commands CSV", name, ["simulate", "--model", "williams2002", "--commands", str(f), "--out",
                                        f"{py}/traj-{len(cases)}.csv"]))
    bomb = work / "bomb.csv.gz"
    bomb.write_bytes(gzip.compress(b"0," * (40 * 2**20)))
    big = work / "big.csv"
    with open(big, "w") as fh:
        fh.write("t,w1,w2,w3\n")
        row = "0.000000,1.000000,1.000000,1.000000\n"
        fh.write(row * (40 * 2**20 // len(row)))
    fifo = work / "fifo.csv"
    os.mkfifo(fifo)
    for name, path in (("/dev/zero", "/dev/zero"), ("/dev/urandom", "/dev/urandom"), ("a pipe", str(fifo)),
                       ("a directory", py), ("missing", f"{py}/missing.csv"), ("gzip bomb", str(bomb)),
                       ("40 MB file", str(big))):
        add(Case("commands CSV", name, ["simulate", "--model", "williams2002", "--commands", path, "--out",
                                        f"{py}/traj-{len(cases)}.csv"]))

    # --- model JSON (model show, simulate --model) ---------------------------------------------
    base = json.loads(subprocess.run([sys.executable, "-m", "omni_gym.cli", "model", "show", "williams2002", "--json"],
                                     capture_output=True, text=True, cwd=ROOT, env=_env()).stdout)
    keys = ["mass", "inertia", "gravity", "wheel_radius", "rollers", "roller_fraction", "body_radius", "com",
            "wheels", "friction", "surface", "effects"]
    valid = {("roller_fraction", "tiny"), ("effects", "object")}  # within the documented bounds: not bad input
    for key in keys:
        for vname, value in _bad_numbers().items():
            if (key, vname) in valid:
                continue
            m = json.loads(json.dumps(base))
            m[key] = value
            f = work / f"model-{len(cases)}.json"
            f.write_text(json.dumps(m))
            add(Case("model JSON", f"{key}={vname}", ["model", "show", str(f)]))
    for sub, values in (("mu_drive", (-1, 1e308, "x")), ("mu_transverse", (-1, 1e308, None)), ("k", (0, 1e308, []))):
        for v in values:
            m = json.loads(json.dumps(base))
            m["surface"][sub] = v
            f = work / f"model-{len(cases)}.json"
            f.write_text(json.dumps(m))
            add(Case("model JSON", f"surface.{sub}={v!r}", ["model", "show", str(f)]))
    for wkey, values in (("position", ([1e308, 0], ["a", 0], [0], None)), ("drive", ([0, 0], [1e308, 1], "x")),
                         ("roller_angle", (1.6, -1e308, "x"))):
        for v in values:
            m = json.loads(json.dumps(base))
            m["wheels"][0][wkey] = v
            f = work / f"model-{len(cases)}.json"
            f.write_text(json.dumps(m))
            add(Case("model JSON", f"wheels[0].{wkey}={v!r}"[:60], ["model", "show", str(f)]))
    from omni_gym.physics.model import EFFECT_PARAMS

    for effect, params in EFFECT_PARAMS.items():
        for param in params:
            for vname, value in (("neg", -1.0), ("huge", 1e308), ("string", "x"), ("null", None)):
                m = json.loads(json.dumps(base))
                m["effects"] = {effect: {param: value}}
                f = work / f"model-{len(cases)}.json"
                f.write_text(json.dumps(m))
                add(Case("model JSON", f"effects.{effect}.{param}={vname}", ["model", "show", str(f)]))
    for preset in ("regular2", "regular17", "regular1e9", "regularx", "regular-3", "nope", "", "../williams2002"):
        add(Case("model JSON", f"preset {preset!r}", ["model", "show", preset]))
    texts = {"nested 100000": "[" * 100_000 + "]" * 100_000, "nested 100": "{\"a\":" * 100 + "1" + "}" * 100,
             "not json": "mass: 1", "empty": "", "trailing comma": '{"mass": 1,}', "NaN": '{"mass": NaN}',
             "Infinity": '{"mass": Infinity}', "5000-digit int": '{"mass": ' + "9" * 5000 + "}", "array": "[1, 2]",
             "duplicate wheels 17": json.dumps({**base, "wheels": base["wheels"] * 6})}
    for name, text in texts.items():
        f = work / f"model-{len(cases)}.json"
        f.write_text(text)
        add(Case("model JSON", name, ["model", "show", str(f)]))
    for name, path in (("/dev/zero", "/dev/zero"), ("a pipe", str(fifo)), ("missing", f"{py}/none.json")):
        add(Case("model JSON", name, ["model", "show", path]))

    # --- datasets (score, calibrate, gap) --------------------------------------------------------
    ds = work / "ds"
    subprocess.run([sys.executable, "-m", "omni_gym.cli", "synth", "--model", "williams2002", "--hidden", "none",
                    "--runs", "1", "--duration", "0.4", "--out", str(ds)], check=True, cwd=ROOT, env=_env(),
                   capture_output=True)
    meta = json.loads((ds / "dataset.json").read_text())
    run_files = sorted((ds / "runs").glob("*.csv"))
    run_text = run_files[0].read_text()

    def dataset_case(name: str, meta_text: str | None = None, run: str | None = None, command: str = "score") -> None:
        d = work / f"ds-{len(cases)}"
        shutil.copytree(ds, d)
        if meta_text is not None:
            (d / "dataset.json").write_text(meta_text)
        if run is not None:
            (d / "runs" / run_files[0].name).write_text(run)
        out = ["--out", f"{py}/rep-{len(cases)}"] if command in ("gap", "calibrate") else []
        add(Case("dataset", f"{command}: {name}", [command, str(d), *out]))

    for key in ("model", "runs", "description"):
        for vname, value in (("null", None), ("number", 1e308), ("string", "x"), ("list", [])):
            if (key, vname) == ("description", "string"):
                continue
            m = dict(meta)
            m[key] = value
            dataset_case(f"{key}={vname}", json.dumps(m))
    for mkey in ("mass", "wheel_radius", "wheels"):
        for vname, value in (("huge", 1e308), ("neg", -1), ("string", "x")):
            m = json.loads(json.dumps(meta))
            m["model"][mkey] = value
            dataset_case(f"model.{mkey}={vname}", json.dumps(m))
    lines = run_text.splitlines()
    header = lines[0]
    for name, change in (("nan cell", lambda c: "nan"), ("huge cell", lambda c: "1e308"), ("text cell", lambda c: "x"),
                         ("digits", lambda c: "9" * 5000), ("minus", lambda c: "-")):
        for col in range(min(5, len(header.split(",")))):
            cells = lines[2].split(",")
            cells[col] = change(cells[col])
            text = "\n".join([*lines[:2], ",".join(cells), *lines[3:]]) + "\n"
            dataset_case(f"run {header.split(',')[col]} {name}", run=text)
    mm = []
    for line in lines[1:]:
        cells = line.split(",")
        for c in (header.split(",").index("x"), header.split(",").index("y")):
            if cells[c].strip():
                cells[c] = f"{float(cells[c]) * 1000 + 1000 * float(cells[0]):.6g}"
        mm.append(",".join(cells))
    dataset_case("positions in millimetres (moving)", run="\n".join([header, *mm]) + "\n")
    for command in ("score", "calibrate", "gap"):
        dataset_case("dataset.json /dev/zero", None, None, command)
        d = work / f"ds-{len(cases) - 1}"
        (d / "dataset.json").unlink()
        (d / "dataset.json").symlink_to("/dev/zero")
        dataset_case("dataset.json nested", "[" * 100_000, None, command)
        dataset_case("run is a pipe", None, None, command)
        d = work / f"ds-{len(cases) - 1}"
        (d / "runs" / run_files[0].name).unlink()
        os.mkfifo(d / "runs" / run_files[0].name)
        dataset_case("dataset.json 5000 digits", '{"model": ' + "9" * 5000 + "}", None, command)
    for name, path in (("missing folder", f"{py}/nope"), ("a file", str(big)), ("/dev/zero", "/dev/zero")):
        add(Case("dataset", f"score: {name}", ["score", path]))
    nested_model = work / "nested-model.json"
    nested_model.write_text("[" * 100_000)
    for name, value in (("/dev/zero", "/dev/zero"), ("a pipe", str(fifo)), ("nested JSON", str(nested_model)),
                        ("unknown preset", "nope"), ("regular99", "regular99"), ("a folder", py)):
        add(Case("dataset", f"score --model {name}", ["score", str(ds), "--model", value]))
    for name, path in (("missing folder", f"{py}/nope"), ("/dev/zero", "/dev/zero"), ("a file", str(big))):
        add(Case("dataset", f"calibrate: {name}", ["calibrate", path, "--out", f"{py}/cal-{len(cases)}"]))

    # --- OptiOdom import ---------------------------------------------------------------------------
    src = ROOT / "data" / "optiodom-omni3" / "circular" / "221220201730"
    meta_name = next(src.glob("*_metadata.csv")).name
    good_meta = (src / meta_name).read_text()

    def optiodom_case(name: str, meta_text: str | None = None, run_scale: float | None = None) -> None:
        d = work / f"oo-{len(cases)}" / src.name
        shutil.copytree(src, d)
        if meta_text is not None:
            (d / meta_name).write_text(meta_text)
        if run_scale is not None:
            for f in d.glob("*_run-*.csv"):
                out = []
                for line in f.read_text().splitlines():
                    cells = line.split(",")
                    cells[1:3] = [f"{float(c) * run_scale:.6g}" if c.strip().lower() != "nan" else c
                                  for c in cells[1:3]]
                    out.append(",".join(cells))
                f.write_text("\n".join(out) + "\n")
        add(Case("OptiOdom import", name, ["import", "optiodom", str(d), "--out", f"{py}/imp-{len(cases)}"]))

    for key, good_value in (("ngear", "12"), ("encRes", "1024"), ("Li", "0.195"), ("Di", "0.102")):
        for bad in ("1e308", "0", "-1", "1e-308", "nan", "inf", "x", "", "9" * 400, "1e400"):
            optiodom_case(f"{key}={bad[:12]}", good_meta.replace(f"{key},{good_value}", f"{key},{bad}", 1))
    for key, bad in (("ngear", "900"), ("encRes", "3")):
        optiodom_case(f"{key}={bad} (in range, wrong scale)",
                      good_meta.replace(f"{key},{'12' if key == 'ngear' else '1024'}", f"{key},{bad}", 1))
    optiodom_case("poses in millimetres", run_scale=1000.0)
    optiodom_case("poses in km", run_scale=0.001)
    optiodom_case("type omni7", good_meta.replace("omni3", "omni7", 1))
    optiodom_case("metadata empty", "")
    d = work / f"oo-{len(cases)}" / src.name
    optiodom_case("metadata /dev/zero")
    (d / meta_name).unlink()
    (d / meta_name).symlink_to("/dev/zero")

    # --- evaluate: policies and keywords -----------------------------------------------------------
    ev = ["evaluate", "--env", "OmniPathFollow-Phunopas-v0", "--episodes", "1", "--env-kwargs",
          '{"episode_seconds": 0.5}']
    for name, text in (("nested 100000", "[" * 100_000), ("5000 digits", "9" * 5000),
                       ("not object", "[1]"), ("bad json", "{x"), ("long string", json.dumps("x" * 100_000)),
                       ("unknown key", '{"nope": 1}'), ("huge speed", '{"max_speed": 1e308}'),
                       ("ref_turn with circle", '{"ref_turn": 1.0, "trajectory": "circle"}'),
                       ("lost below success", '{"lost_distance": 0.001, "success_distance": 1.0}'),
                       ("model /dev/zero", '{"model": "/dev/zero"}'), ("episode 1e308", '{"episode_seconds": 1e308}')):
        add(Case("evaluate", f"--env-kwargs {name}", ["evaluate", "--policy", "ekf-pid", "--env",
                                                      "OmniPathFollow-Phunopas-v0", "--episodes", "1",
                                                      "--env-kwargs", text]))
    model = ROOT / "agents" / "models" / "ppo-residual"
    for i, (key, value) in enumerate((("model", "../../../../etc/passwd"), ("model", "/etc/passwd"),
                                      ("vecnormalize", "../x.npz"), ("model", "/dev/zero"), ("algo", "dqn"),
                                      ("policy", {"class": "os.system"}), ("policy", None),
                                      ("wrapper", "evil"))):
        d = work / f"model-dir-{i}"
        shutil.copytree(model, d)
        m = json.loads((d / "meta.json").read_text())
        m[key] = value
        (d / "meta.json").write_text(json.dumps(m))
        add(Case("evaluate", f"meta.json {key}={str(value)[:30]}", ["evaluate", "--policy", str(d), *ev[1:]]))
    for i, (fname, kind) in enumerate((("policy.pt", "pickle"), ("normalisation.npz", "pickle"),
                                       ("policy.pt", "garbage"), ("policy.pt", "empty"), ("meta.json", "nested"))):
        d = work / f"model-file-{i}"
        shutil.copytree(model, d)
        marker = work / f"marker-file-{i}"
        if kind == "pickle" and fname == "policy.pt":
            import torch

            torch.save({"x": _Marker(str(marker))}, d / fname)
        elif kind == "pickle":
            (d / fname).write_bytes(_payload(marker))
        elif kind == "garbage":
            (d / fname).write_bytes(os.urandom(4096))
        elif kind == "nested":
            (d / fname).write_text("[" * 100_000)
        else:
            (d / fname).write_bytes(b"")
        add(Case("evaluate", f"{fname} {kind}", ["evaluate", "--policy", str(d), *ev[1:]], marker=marker))
    for i in range(4):
        marker = work / f"marker-zip-{i}"
        z = work / f"evil-{i}.zip"
        entry = {":type:": "x", ":serialized:": base64.b64encode(_payload(marker)).decode()}
        with zipfile.ZipFile(z, "w") as zf:
            zf.writestr("data", json.dumps({"policy_class": entry, "observation_space": entry}))
        algo = ("ppo", "sac", "td3", "ppo")[i]
        extra = ["--vecnormalize", str(z)] if i == 3 else []
        label = f"crafted SB3 zip ({algo}{', --vecnormalize' if extra else ''})"
        add(Case("evaluate", label, ["evaluate", "--policy", str(z), "--algo", algo, *extra, *ev[1:]], marker=marker))
    marker = work / "marker-zoo"
    zoo = work / "zoo"
    (zoo / "OmniPathFollow-Phunopas-v0").mkdir(parents=True)
    with zipfile.ZipFile(zoo / "OmniPathFollow-Phunopas-v0.zip", "w") as zf:
        zf.writestr("data", json.dumps({"x": {":serialized:": base64.b64encode(_payload(marker)).decode()}}))
    (zoo / "OmniPathFollow-Phunopas-v0" / "args.yml").write_text("algo: ppo\n")
    (zoo / "OmniPathFollow-Phunopas-v0" / "config.yml").write_text("normalize: true\n")
    (zoo / "OmniPathFollow-Phunopas-v0" / "vecnormalize.pkl").write_bytes(_payload(marker))
    add(Case("evaluate", "crafted RL Zoo folder", ["evaluate", "--policy", str(zoo), *ev[1:]], marker=marker))
    marker = work / "marker-rllib"
    ck = work / "rllib-ckpt"
    mod = ck.joinpath("learner_group", "learner", "rl_module", "default_policy")
    mod.mkdir(parents=True)
    (ck / "rllib_checkpoint.json").write_text("{}")
    (mod / "class_and_ctor_args.pkl").write_bytes(_payload(marker))
    add(Case("evaluate", "crafted RLlib checkpoint", ["evaluate", "--policy", str(ck), *ev[1:]], marker=marker))
    for opt, values in (("--episodes", ("0", "-1", "1e9", "x")), ("--seed", ("-1", "1e30", "x")),
                        ("--env", ("Nope-v0", "", "../../x")), ("--policy", ("nope", "/dev/zero", py))):
        for v in values:
            argv = ["evaluate", "--policy", "ekf-pid", "--env", "OmniPathFollow-Phunopas-v0", "--episodes", "1",
                    "--seed", "0"]
            argv[argv.index(opt) + 1] = v
            add(Case("evaluate", f"{opt} {v[:20]}", argv))

    # --- train --hyperparams -----------------------------------------------------------------------
    env_id = "OmniPathFollow-Phunopas-v0"
    levels = ["a: &a [x, x, x, x, x, x, x, x, x]"] + [
        f"{chr(98 + k)}: &{chr(98 + k)} [" + ", ".join([f"*{chr(97 + k)}"] * 9) + "]" for k in range(8)]
    ymls = {
        "alias bomb": "\n".join(levels) + "\n", "small alias bomb": "\n".join(levels[:5]) + "\n",
        "python tag": f"{env_id}: !!python/object/apply:os.system ['true']\n",
        "policy_kwargs import": f"{env_id}: {{policy_kwargs: \"dict(x=__import__('os'))\"}}\n",
        "policy_kwargs builtins":
            f"{env_id}: {{policy_kwargs: \"dict(activation_fn=nn.modules.module.__builtins__['exec'])\"}}\n",
        "policy_kwargs lambda": f"{env_id}: {{policy_kwargs: \"(lambda: 1)()\"}}\n",
        "policy_kwargs unknown class": f"{env_id}: {{policy_kwargs: \"dict(activation_fn=os.system)\"}}\n",
        "policy_kwargs huge list": f"{env_id}: {{policy_kwargs: \"dict(net_arch=[64] * 10**9)\"}}\n",
        "not a mapping": "[1, 2]\n", "bad yaml": "a: [1, 2\n", "empty": "",
        "nested": "a: " + "[" * 10_000 + "\n", "n_steps negative": f"{env_id}: {{n_steps: -1}}\n",
        "gamma huge": f"{env_id}: {{gamma: 1e308}}\n", "batch digits": f"{env_id}: {{batch_size: {'9' * 400}}}\n",
        "learning_rate text": f"{env_id}: {{learning_rate: fast}}\n",
        "buffer huge": f"{env_id}: {{buffer_size: 1e12}}\n",
        "unknown env": "Other-v0: {n_timesteps: 10}\n", "latin-1": None, "binary": None,
    }
    for name, text in ymls.items():
        f = work / f"hp-{len(cases)}.yml"
        if name == "latin-1":
            f.write_bytes("gamma: \xe9\n".encode("latin-1"))
        elif name == "binary":
            f.write_bytes(os.urandom(2048))
        else:
            f.write_text(text)
        add(Case("train --hyperparams", name, ["train", "--algo", "ppo", "--env", env_id, "--hyperparams", str(f),
                                                "--out", f"{py}/train-{len(cases)}", "--no-progress"]))
    for name, path in (("/dev/zero", "/dev/zero"), ("a pipe", str(fifo)), ("missing", f"{py}/none.yml")):
        add(Case("train --hyperparams", name, ["train", "--algo", "ppo", "--env", env_id, "--hyperparams", path,
                                                "--out", f"{py}/train-{len(cases)}", "--no-progress"]))

    # --- synth and gap options ---------------------------------------------------------------------
    for hidden in ("motor_lag:", "motor_lag:{", "motor_lag:[]", 'motor_lag:{"tau": 1e308}', 'motor_lag:{"x": 1}',
                   "motor_lag:" + "[" * 100_000, 'motor_lag:{"tau": ' + "9" * 5000 + "}", "nope", ":", "",
                   'viscous_drag:{"c": -1}', 'wheel_liftoff:{"lift_rate": 1e308}', "none:{}"):
        add(Case("synth", f"--hidden {hidden[:30]}", ["synth", "--model", "williams2002", "--hidden", hidden,
                                                       "--out", f"{py}/syn-{len(cases)}"]))
    for opt, values in (("--runs", ("0", "-1", "1e9", "x", "2000")), ("--duration", ("0", "-1", "1e308", "nan", "inf")),
                        ("--noise", ("-1", "1e308", "nan")), ("--seed", ("-1", "1e30", "2.5"))):
        for v in values:
            add(Case("synth", f"{opt} {v}", ["synth", "--model", "williams2002", "--hidden", "none", opt, v,
                                              "--out", f"{py}/syn-{len(cases)}"]))
    for opt, values in (("--jobs", ("0", "-1", "x", "1e9")), ("--max-effects", ("0", "-1", "1000")),
                        ("--fit-budget", ("0", "-1", "nan", "1e308")), ("--seed", ("-1", "x"))):
        for v in values:
            add(Case("gap options", f"{opt} {v}", ["gap", str(ds), "--out", f"{py}/gap-{len(cases)}", opt, v]))
    for v in ("0", "-1", "nan", "1e308", "x"):
        add(Case("global options", f"--max-input-mb {v}", ["--max-input-mb", v, "model", "show", "williams2002"]))
    for v in ("0", "-1", "1", "nan", "x"):
        add(Case("global options", f"simulate --dt {v}", ["simulate", "--model", "williams2002", "--commands",
                                                           str(work / "cmd-0.csv"), "--out", f"{py}/t.csv", "--dt", v]))
    return cases


def build_hostile_cases(work: Path) -> list[Case]:
    """Hostile inputs: writes outside --out through run names, --force on a FIFO, a model folder's env_id that
    imports a module, garbage gzip, a bag claiming zstd, deep JSON to export, escape sequences echoed, huge
    networks and buffers in train, an unreachable Ray address (which must be refused within 15 s), a numpy
    warning printed before the error. Categories start with "hostile" (``--only hostile`` runs just these)."""
    cases: list[Case] = []
    add = cases.append
    h = work / "hostile"
    h.mkdir()
    env_id = "OmniPathFollow-Phunopas-v0"
    columns = "t=t,x=x,y=y,theta=theta,enc1=enc1,enc2=enc2,enc3=enc3"
    subprocess.run([sys.executable, "-m", "omni_gym.cli", "synth", "--model", "williams2002", "--hidden", "none",
                    "--runs", "1", "--duration", "2", "--out", str(h / "ds")], check=True, cwd=ROOT, env=_env(),
                   capture_output=True)
    log = h / "robot.csv"
    shutil.copyfile(h / "ds" / "runs" / "run000.csv", log)
    csv_import = ["import", "csv", str(log), "--model", "williams2002", "--columns", columns]

    # run names that are paths: nothing may appear outside --out
    (h / "abs").mkdir()
    names = ((f"{h}/abs/evil", h / "abs" / "evil.csv"), ("../../evil-up", h / "evil-up.csv"),
             ("../evil-in", h / "imp-w2" / "evil-in.csv"), ("..", None))
    for i, (name, written) in enumerate(names):
        add(Case("hostile: run names", f"--window {name[-12:]}=0:1", [*csv_import, "--window", f"{name}=0:1",
                                                                       "--out", f"{h}/imp-w{i}"], outside=written))
    mapping = h / "mapping.json"
    mapping.write_text(json.dumps({"model": "williams2002", "columns": columns, "window": ["../../evil-map=0:1"]}))
    add(Case("hostile: run names", "mapping window ../../evil-map", ["import", "csv", str(log), "--mapping",
                                                                      str(mapping), "--out", f"{h}/imp-map"],
             outside=h / "evil-map.csv"))
    try:
        from omni_gym.discrepancy.synthetic.bags import write_bag
        from omni_gym.discrepancy.synthetic.synth import synthesize
        from omni_gym.physics.model import load_model

        runs, _ = synthesize(load_model("williams2002"), "none", runs=1, noise=0.0, seed=5, duration=1.0)
        r = runs[0]
        joints = ["wl", "wr", "wb"]
        bag_args = ["--model", "williams2002", "--joints", "wl,-wr,wb", "--pose-topic", "/tracker/pose"]
        write_bag(h / "bag", [(r.t, r.enc, r.pose)], joints, [1.0, -1.0, 1.0])
        add(Case("hostile: run names", "rosbag2 --window ../../evil-bag", ["import", "rosbag2", str(h / "bag"),
                                                                           *bag_args, "--window", "../../evil-bag=0:1",
                                                                           "--out", f"{h}/imp-bag"],
                 outside=h / "evil-bag.csv"))
        for mode in ("MESSAGE", "FILE"):
            z = h / f"bag-zstd-{mode.lower()}"
            shutil.copytree(h / "bag", z)
            meta = (z / "metadata.yaml").read_text()
            (z / "metadata.yaml").write_text(meta.replace("compression_format: ''", "compression_format: zstd")
                                             .replace("compression_mode: ''", f"compression_mode: {mode}"))
            add(Case("hostile: damaged files", f"bag claiming zstd ({mode})", ["import", "rosbag2", str(z), *bag_args,
                                                                                "--out", f"{h}/imp-{z.name}"]))
        write_bag(h / "bag-esc", [(r.t, r.enc, r.pose)], joints, [1.0, -1.0, 1.0], frame="w\x1b[31mRED\nforged")
        add(Case("hostile: messages", "bag frame_id with an escape sequence",
                 ["import", "rosbag2", str(h / "bag-esc"), *bag_args, "--frames", "world:base_link", "--out",
                  f"{h}/imp-esc"]))
    except ImportError:  # rosbags missing: the bag cases are left out
        pass

    # --force on something that is not a regular file (a FIFO stands in for /dev/full)
    for command, argv in (("simulate", ["simulate", "--model", "williams2002", "--commands", str(h / "cmd.csv")]),
                          ("calibrate", ["calibrate", str(h / "ds")])):
        (h / "cmd.csv").write_text("t,w1,w2,w3\n0,1,1,1\n0.1,1,1,1\n")
        fifo = h / f"fifo-{command}"
        os.mkfifo(fifo)
        add(Case("hostile: --force", f"{command} --out FIFO --force", [*argv, "--out", str(fifo), "--force"],
                 fifo=fifo))
        link = h / f"link-{command}"
        link.symlink_to(fifo)
        add(Case("hostile: --force", f"{command} --out link-to-FIFO --force", [*argv, "--out", str(link), "--force"],
                 fifo=fifo))

    # a model folder whose env_id imports a module (the module writes the marker when imported)
    model = ROOT / "agents" / "models" / "ppo-residual"
    (h / "pymod").mkdir()
    marker = h / "marker-envid"
    (h / "pymod" / "probe_evil_env.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    for command in ("export", "evaluate"):
        d = h / f"model-envid-{command}"
        shutil.copytree(model, d)
        meta = json.loads((d / "meta.json").read_text())
        meta["env_id"] = f"probe_evil_env:{env_id}"
        (d / "meta.json").write_text(json.dumps(meta))
        argv = (["export", str(d), "--out", f"{h}/exp-{command}"] if command == "export" else
                ["evaluate", "--policy", str(d), "--env", env_id, "--episodes", "1"])
        add(Case("hostile: model folders", f"{command}: env_id MODULE:ID", argv, marker=marker,
                 env={"PYTHONPATH": f"{ROOT}{os.pathsep}{h / 'pymod'}"}))
    d = h / "model-deep"
    shutil.copytree(model, d)
    (d / "meta.json").write_text("[" * 100_000 + "]" * 100_000)
    add(Case("hostile: damaged files", "export: meta.json nested 100000", ["export", str(d), "--out", f"{h}/exp-deep"]))

    # garbage gzip in an OptiOdom session
    src = ROOT / "data" / "optiodom-omni3" / "circular" / "221220201730"
    for name, data in (("zlib garbage", b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\x03garbage"),
                       ("not gzip", b"plain text"), ("truncated", None)):
        d = h / f"oo-{name.replace(' ', '-')}" / src.name
        shutil.copytree(src, d)
        run = next(d.glob("*_run-01.csv"))
        data = gzip.compress(run.read_bytes())[:300] if data is None else data
        run.unlink()
        run.with_name(run.name + ".gz").write_bytes(data)
        add(Case("hostile: damaged files", f"optiodom run-01.csv.gz {name}", ["import", "optiodom", str(d), "--out",
                                                                             f"{h}/imp-oo-{name.replace(' ', '-')}"]))

    # escape sequences in a name echoed by the error; a numpy warning before the error
    add(Case("hostile: messages", "file name with an escape sequence", ["simulate", "--model", "williams2002",
                                                                        "--commands", f"{h}/a\x1b]0;x\x07.csv",
                                                                        "--out", f"{h}/t.csv"]))
    lines = log.read_text().splitlines()
    cells = lines[4].split(",")
    cells[4] = "1e308"
    (h / "overflow.csv").write_text("\n".join([*lines[:4], ",".join(cells), *lines[5:]]) + "\n")
    add(Case("hostile: messages", "wheel angle 1e308 (overflow warning)", ["import", "csv", str(h / "overflow.csv"),
                                                                           "--model", "williams2002", "--columns",
                                                                           columns, "--out", f"{h}/imp-overflow"]))

    # train: huge networks and buffers, an unreachable Ray address
    sizes = (("net_arch [1e8, 1e8]", '{policy_kwargs: "dict(net_arch=[100000000, 100000000])"}', "ppo"),
             ("net_arch qf [20000, 20000]", "{policy_kwargs: {net_arch: {pi: [64], qf: [20000, 20000]}}}", "sac"),
             ("buffer_size 1e8", "{buffer_size: 100000000}", "sac"),
             ("n_steps 1e6 x n_envs 64", "{n_steps: 1000000, n_envs: 64}", "ppo"))
    for name, entry, algo in sizes:
        f = h / f"hp-{len(cases)}.yml"
        f.write_text(f"{env_id}: {entry}\n")
        add(Case("hostile: train sizes", name, ["train", "--algo", algo, "--env", env_id, "--hyperparams", str(f),
                                                 "--timesteps", "10", "--out", f"{h}/train-{len(cases)}",
                                                 "--no-progress"]))
    add(Case("hostile: train sizes", "rllib --address 256.1.1.1:1 (15 s bound)",
             ["train", "--backend", "rllib", "--env", env_id, "--address", "256.1.1.1:1", "--out", f"{h}/train-ray",
              "--no-progress"], time_limit=15.0))
    add(Case("hostile: train sizes", "gap --ray 256.1.1.1:1 (15 s bound)",
             ["gap", str(h / "ds"), "--ray", "256.1.1.1:1", "--out", f"{h}/gap-ray"], time_limit=15.0))
    return cases


def _cli(*argv: str) -> None:
    """Run one ``omni-gym`` command while building cases (a dataset to damage); it must succeed."""
    subprocess.run([sys.executable, "-m", "omni_gym.cli", *argv], check=True, cwd=ROOT, env=_env(),
                   capture_output=True)


def _edit_csv(src: Path, dst: Path, row: int, changes: dict[str, str]) -> Path:
    """Copy the CSV ``src`` to ``dst`` with the cells of data row ``row`` (0 = first after the header) replaced,
    by column name."""
    lines = src.read_text().splitlines()
    header = lines[0].split(",")
    cells = lines[row + 1].split(",")
    for col, value in changes.items():
        cells[header.index(col)] = value
    lines[row + 1] = ",".join(cells)
    dst.write_text("\n".join(lines) + "\n")
    return dst


def _scale_columns(src: Path, dst: Path, factors: dict[str, float]) -> Path:
    """Copy the CSV ``src`` to ``dst`` with whole columns multiplied (a log written in other units)."""
    lines = src.read_text().splitlines()
    header = lines[0].split(",")
    out = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        for col, f in factors.items():
            j = header.index(col)
            if cells[j].strip():
                cells[j] = repr(float(cells[j]) * f)
        out.append(",".join(cells))
    dst.write_text("\n".join(out) + "\n")
    return dst


def build_command_cases(work: Path) -> list[Case]:
    """Per subcommand: ``import csv`` and ``import rosbag2`` options and logs, ``calibrate``, ``evaluate --plant``,
    ``export``, and more of ``score``, ``simulate`` and ``model show``; then the bad inputs that used to be
    accepted silently (a heading of 99999 rad, 3000 rad/s wheel commands, ``synth --noise 5``, an OptiOdom row
    of NaN). A few cases are good inputs that must be accepted (``expect="ok"``: a CSV with a byte-order mark
    and CRLF line ends, a tracking dropout)."""
    cases: list[Case] = []
    add = cases.append
    c = work / "commands"
    c.mkdir()
    out = lambda tag: f"{c}/out-{tag}-{len(cases)}"  # noqa: E731  a fresh --out per case
    # a 3-wheel log that imports as is: the Williams robot on a floor that grips (no slip, so that a unit mistake
    # shows as the ratio of tracked to wheel motion), turning 2 rad in 3 s (seed 1), with the synthetic tracker's noise
    _cli("synth", "--model", "williams2002", "--surface", "grip", "--hidden", "none", "--runs", "2", "--duration", "3",
         "--seed", "1", "--out", str(c / "ds"))
    log = c / "robot.csv"
    shutil.copyfile(c / "ds" / "runs" / "run000.csv", log)
    text = log.read_text()
    columns = "t=t,x=x,y=y,theta=theta,enc1=enc1,enc2=enc2,enc3=enc3"
    wmodel = "williams2002"

    def csv_case(name: str, path: Path | str = log, *opts: str, cols: str | None = columns, model: str | None = wmodel,
                 expect: str = "refuse") -> None:
        argv = ["import", "csv", str(path), *(["--model", model] if model else []),
                *(["--columns", cols] if cols is not None else []), *opts, "--out", out("csv")]
        add(Case("import csv", name, argv, expect=expect))

    csv_case("good log (accepted)", expect="ok")
    # --columns maps
    for name, cols in (("--columns empty", ""), ("--columns t only", "t=t"),
                       ("--columns no wheels", "t=t,x=x,y=y,theta=theta"),
                       ("--columns entry without =", "t,x=x,y=y,theta=theta,enc1=enc1,enc2=enc2,enc3=enc3"),
                       ("--columns t=(empty)", "t=,x=x,y=y,theta=theta,enc1=enc1,enc2=enc2,enc3=enc3"),
                       ("--columns t twice", columns + ",t=t"), ("--columns signed x", columns.replace("x=x", "x=-x")),
                       ("--columns two wheels of three", "t=t,x=x,y=y,theta=theta,enc1=enc1,enc2=enc2"),
                       ("--columns four wheels of three", columns + ",enc4=enc1"),
                       ("--columns angles and speeds", columns + ",w1=w1"),
                       ("--columns unknown name", columns + ",speed=w1"),
                       ("--columns unknown column", columns.replace("enc3=enc3", "enc3=wheel_rear")),
                       ("--columns theta from a wheel column", columns.replace("theta=theta", "theta=enc1")),
                       ("--columns w1..w3 from a pose column", "t=t,x=x,y=y,theta=theta,w1=x,w2=w2,w3=w3"),
                       ("--columns x and y the same column", columns.replace("y=y", "y=x")),
                       ("--columns 5000 commas", "," * 5000)):
        csv_case(name, log, cols=cols)
    csv_case("no --columns", cols=None)
    csv_case("no --model", model=None)
    csv_case("--model unknown preset", model="williams2003")
    csv_case("--model with four wheels, three wheel columns", model="regular4")
    # --units
    for units in ("furlong", "mm,cm", "deg,rad", "ms,s", "wheel=", "wheel=furlong", "wheel=mm", "MM", "m;rad",
                  "wheel=rev,wheel=rad"):
        csv_case(f"--units {units}", log, "--units", units)
    # unit mistakes: the log is in m, rad, s, rad
    for name, units in (("poses in metres read as mm", "mm"), ("poses in metres read as cm", "cm"),
                        ("wheel angles in rad read as deg", "wheel=deg"),
                        ("wheel angles in rad read as revolutions", "wheel=rev"),
                        ("joint angles read as rpm", "wheel=rpm"), ("theta and wheels in rad read as deg", "deg"),
                        ("times in s read as ms", "ms")):
        csv_case(f"unit mistake: {name} (--units {units})", log, "--units", units)
    mm_log = _scale_columns(log, c / "robot-mm.csv", {"x": 1000.0, "y": 1000.0})
    csv_case("unit mistake: poses in mm read as metres", mm_log)
    deg_log = _scale_columns(log, c / "robot-deg.csv", {"theta": 180.0 / 3.141592653589793})
    csv_case("unit mistake: theta in degrees read as rad", deg_log)
    csv_case("good log in mm with --units mm (accepted)", mm_log, "--units", "mm", expect="ok")
    # --window and --max-gap
    for w in ("5:10", "-1:1", "1:0", "x:y", "1:1", "nan:1", "inf:", "0:0.01", "1", "", "0:1:2", "a/b=0:1",
              ".hidden=0:1"):
        csv_case(f"--window {w!r}", log, "--window", w)
    csv_case("--window twice with one name", log, "--window", "a=0:1", "--window", "a=1:2")
    for g in ("0", "-1", "nan", "1e308", "x"):
        csv_case(f"--max-gap {g}", log, "--max-gap", g)
    # file contents
    lines = text.splitlines()
    header = lines[0]
    bom = c / "bom-crlf.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + "\r\n".join(lines).encode() + b"\r\n")
    csv_case("BOM and CRLF line ends (accepted)", bom, expect="ok")
    crlf = c / "crlf.csv"
    crlf.write_bytes("\r\n".join(lines).encode() + b"\r\n")
    csv_case("CRLF line ends (accepted)", crlf, expect="ok")
    for name, col, value in (("x NaN", "x", "nan"), ("enc2 NaN", "enc2", "NaN"), ("theta inf", "theta", "inf"),
                             ("y -inf", "y", "-inf"), ("x 1e308", "x", "1e308"), ("enc1 1e308", "enc1", "1e308"),
                             ("enc1 1e6 rad", "enc1", "1e6"), ("t 1e308", "t", "1e308"),
                             ("x 5000 digits", "x", "9" * 5000), ("enc3 hex", "enc3", "0x1f"),
                             ("time empty", "t", ""), ("x empty, y and theta given", "x", ""),
                             ("enc1 empty, enc2 and enc3 given", "enc1", ""), ("t repeats the row before", "t", "0.0"),
                             ("x text", "x", "north")):
        row = 1 if (col, value) == ("t", "0.0") else 5  # row 1's time = row 0's
        f = _edit_csv(log, c / f"cell-{len(cases)}.csv", row, {col: value})
        csv_case(f"cell: {name}", f)
    frozen = c / "frozen.csv"
    frozen.write_text("\n".join([header, *(",".join(ln.split(",")[:5] + ["0.0"] + ln.split(",")[6:])
                                           for ln in lines[1:])]) + "\n")
    csv_case("a frozen encoder (enc2 always 0)", frozen)
    for name, content in (("empty file", ""), ("header only", header + "\n"), ("one data row", "\n".join(lines[:2])),
                          ("duplicate column x", header + ",x\n" + "\n".join(ln + ",0" for ln in lines[1:])),
                          ("semicolons", "\n".join(ln.replace(",", ";") for ln in lines)),
                          ("latin-1 header", None), ("binary", None)):
        f = c / f"content-{len(cases)}.csv"
        if name == "latin-1 header":
            f.write_bytes(text.replace("theta", "th\xe9ta", 1).encode("latin-1"))
        elif name == "binary":
            f.write_bytes(os.urandom(4096))
        else:
            f.write_text(content)
        csv_case(f"file: {name}", f)
    fifo = c / "fifo.csv"
    os.mkfifo(fifo)
    for name, path in (("missing", c / "none.csv"), ("a directory", c), ("/dev/zero", "/dev/zero"), ("a pipe", fifo)):
        csv_case(f"file: {name}", path)
    csv_case("the log twice (two runs of one name)", log, str(log))
    # options of another format
    for opt in (["--joints", "a,b,c"], ["--pose-topic", "/pose"], ["--frames", "world:base"],
                ["--joint-topic", "/js"], ["--command-topic", "/cmd"], ["--wheel-field", "velocity"],
                ["--mass", "3"], ["--inertia", "0.1"], ["--time-base", "file"]):
        csv_case(f"option of another format: {opt[0]}", log, *opt)
    # --mapping files
    for name, mapping in (("unknown key", {"columns": columns, "colums": columns}),
                          ("a key of rosbag2 (joints)", {"joints": "a,b,c"}), ("a key of optiodom (mass)", {"mass": 3}),
                          ("not an object", [columns]), ("window not a list", {"window": "0:1"}),
                          ("max_gap a string", {"max_gap": "0.25"}), ("columns a number", {"columns": 7}),
                          ("model null", {"model": None}), ("units an object", {"units": {"length": "mm"}}),
                          ("nested 100000", None)):
        f = c / f"mapping-{len(cases)}.json"
        f.write_text(json.dumps(mapping) if mapping is not None else "[" * 100_000)
        csv_case(f"--mapping {name}", log, "--mapping", str(f))
    for name, path in (("missing", c / "none.json"), ("/dev/zero", "/dev/zero")):
        csv_case(f"--mapping {name}", log, "--mapping", str(path))

    # --- import rosbag2 --------------------------------------------------------------------------------
    try:
        from omni_gym.discrepancy.synthetic.bags import write_bag
        from omni_gym.discrepancy.synthetic.synth import synthesize
        from omni_gym.physics.model import load_model

        runs, _ = synthesize(load_model(wmodel, "grip"), "none", runs=1, noise=0.0, seed=1, duration=3.0)
        r = runs[0]
        write_bag(c / "bag", [(r.t, r.enc, r.pose)], ["wl", "wr", "wb"], [1.0, -1.0, 1.0])
        write_bag(c / "bag-mm", [(r.t, r.enc, r.pose)], ["wl", "wr", "wb"], [1.0, -1.0, 1.0], length_scale=1000.0)
        have_bags = True
    except ImportError:  # rosbags missing: the bag cases are left out
        have_bags = False
    if have_bags:
        bag = ["--model", wmodel, "--joints", "wl,-wr,wb", "--pose-topic", "/tracker/pose"]

        def bag_case(name: str, *argv: str, path: Path | str = c / "bag", expect: str = "refuse") -> None:
            add(Case("import rosbag2", name, ["import", "rosbag2", str(path), *argv, "--out", out("bag")],
                     expect=expect))

        bag_case("good bag (accepted)", *bag, expect="ok")
        for name, joints in (("two joints of three", "wl,-wr"), ("four joints of three", "wl,-wr,wb,wl"),
                             ("unknown joint", "wl,-wr,wheel9"), ("a joint twice", "wl,wl,wb"), ("empty", ""),
                             ("signs only", "-,-,-"), ("wrong sign (-wl)", "-wl,-wr,wb")):
            bag_case(f"--joints {name}", "--model", wmodel, "--joints", joints, "--pose-topic", "/tracker/pose")
        for name, extra in (("--pose-topic missing topic", ["--pose-topic", "/mocap/nope"]),
                            ("--joint-topic missing topic", ["--joint-topic", "/nope"]),
                            ("--command-topic missing topic", ["--command-topic", "/nope"]),
                            ("--frames one frame", ["--frames", "world"]),
                            ("--frames wrong parent", ["--frames", "map:base_link"]),
                            ("--wheel-field effort", ["--wheel-field", "effort"]),
                            ("--wheel-field velocity on a position log", ["--wheel-field", "velocity"]),
                            ("--columns (csv's option)", ["--columns", columns]),
                            ("--mass (optiodom's option)", ["--mass", "3"]),
                            ("--window beyond the bag", ["--window", "10:20"]),
                            ("--max-gap 0", ["--max-gap", "0"]),
                            ("poses in metres read as mm", ["--units", "mm"]),
                            ("joint angles read as rpm", ["--units", "wheel=rpm"]),
                            ("joint angles in rad read as deg", ["--units", "wheel=deg"])):
            argv = list(bag)
            if extra[0] in argv:  # replace the good value
                argv[argv.index(extra[0]) + 1] = extra[1]
                extra = []
            bag_case(name, *argv, *extra)
        bag_case("poses in mm read as metres", *bag, path=c / "bag-mm")
        bag_case("no --joints", "--model", wmodel, "--pose-topic", "/tracker/pose")
        for name, mutate in (("metadata.yaml missing", "unlink"), ("metadata.yaml garbage", "garbage"),
                             ("metadata.yaml nested", "nested"), ("database truncated", "truncate")):
            d = c / f"bag-{len(cases)}"
            shutil.copytree(c / "bag", d)
            if mutate == "unlink":
                (d / "metadata.yaml").unlink()
            elif mutate == "garbage":
                (d / "metadata.yaml").write_bytes(os.urandom(512))
            elif mutate == "nested":
                (d / "metadata.yaml").write_text("a: " + "[" * 10_000 + "\n")
            else:
                for f in d.glob("*.db3"):
                    f.write_bytes(f.read_bytes()[:2048])
            bag_case(name, *bag, path=d)
        for name, path in (("missing folder", c / "nobag"), ("a file", log), ("/dev/zero", "/dev/zero")):
            bag_case(f"bag: {name}", *bag, path=path)

    # --- calibrate ---------------------------------------------------------------------------------------
    src = ROOT / "data" / "optiodom-omni3" / "circular" / "221220201730"
    good = c / "oo-ds"  # a dataset calibrate fits (the shipped OptiOdom session)
    _cli("import", "optiodom", str(src), "--out", str(good))
    run_names = sorted(p.name for p in (good / "runs").glob("*.csv"))

    def cal_case(name: str, dataset: Path | str, *argv: str, out_path: str | None = None) -> None:
        add(Case("calibrate", name, ["calibrate", str(dataset), "--out", out_path or f"{out('cal')}.json", *argv]))

    def damaged(tag: str, change) -> Path:
        d = c / f"cal-{tag}-{len(cases)}"
        shutil.copytree(good, d)
        for n in run_names:
            f = d / "runs" / n
            lines = f.read_text().splitlines()
            hdr = lines[0].split(",")
            f.write_text("\n".join([change(lines[0], hdr, None), *(change(ln, hdr, ln.split(",")) for ln in
                                                                   lines[1:])]) + "\n")
        return d

    def drop_enc(line, hdr, cells):
        keep = [i for i, h in enumerate(hdr) if not h.startswith("enc")]
        return ",".join((line.split(","))[i] for i in keep)

    def freeze_enc2(line, hdr, cells):
        if cells is None:
            return line
        cells[hdr.index("enc2")] = "0.0"
        return ",".join(cells)

    def no_pose(line, hdr, cells):
        if cells is None:
            return line
        for k in ("x", "y", "theta"):
            cells[hdr.index(k)] = "" if cells[0] != "0.0" else cells[hdr.index(k)]
        return ",".join(cells)

    _cli("synth", "--model", wmodel, "--surface", "carpet", "--hidden", "none", "--runs", "2", "--duration", "2",
         "--out", str(c / "carpet"))
    cal_case("missing dataset", c / "no-dataset")
    cal_case("dataset without encoders", damaged("noenc", drop_enc))
    cal_case("a frozen encoder (enc2 always 0)", damaged("frozen", freeze_enc2))
    cal_case("no tracked pose after the first row", damaged("nopose", no_pose))
    cal_case("a slipping robot on carpet (values at bounds)", c / "carpet")
    cal_case("--tracker on a slipping robot", c / "carpet", "--tracker")
    # missing parent folders of --out are created for the run and removed when it is refused (docs/formats.md)
    add(Case("calibrate", "--out into a missing folder (created, accepted)", ["calibrate", str(good), "--out",
                                                                             f"{c}/new-folder/model.json"],
             expect="ok"))
    add(Case("calibrate", "--out into a missing folder, refused (no folder left)",
             ["calibrate", str(c / "carpet"), "--out", f"{c}/gone-folder/sub/model.json"],
             outside=c / "gone-folder"))
    cal_case("--out an existing folder", good, out_path=str(c))
    (c / "existing.json").write_text("{}")
    cal_case("--out an existing file without --force", good, out_path=str(c / "existing.json"))
    cal_case("--out the dataset's own dataset.json --force", good, "--force", out_path=str(good / "dataset.json"))
    cal_case("--out the dataset folder --force", good, "--force", out_path=str(good))
    fifo_cal = c / "fifo-cal"
    os.mkfifo(fifo_cal)
    add(Case("calibrate", "--out a FIFO --force", ["calibrate", str(good), "--out", str(fifo_cal), "--force"],
             fifo=fifo_cal))
    cal_case("--out a FIFO without --force", good, out_path=str(fifo_cal))
    cal_case("--out /dev/null --force", good, "--force", out_path="/dev/null")
    cal_case("dataset a file", log)

    # --- evaluate --plant --------------------------------------------------------------------------------
    ev = ["evaluate", "--policy", "ekf-pid", "--env", "OmniPathFollow-Phunopas-v0", "--episodes", "1"]
    (c / "garbage-model.json").write_bytes(os.urandom(300))
    (c / "w3.json").write_text(subprocess.run([sys.executable, "-m", "omni_gym.cli", "model", "show", wmodel,
                                               "--json"], capture_output=True, text=True, cwd=ROOT,
                                              env=_env()).stdout)
    (c / "not-model.json").write_text('{"mass": 1}')
    for name, argv in (
            ("--plant-model missing", ["--plant", "second-generator", "--plant-model", f"{c}/none.json"]),
            ("--plant-model garbage", ["--plant", "second-generator", "--plant-model", f"{c}/garbage-model.json"]),
            ("--plant-model not a model", ["--plant", "simulator", "--plant-model", f"{c}/not-model.json"]),
            ("--plant-model /dev/zero", ["--plant", "simulator", "--plant-model", "/dev/zero"]),
            ("--plant-model 3 wheels, env 4 (second-generator)",
             ["--plant", "second-generator", "--plant-model", f"{c}/w3.json"]),
            ("--plant-model 3 wheels, env 4 (simulator)", ["--plant", "simulator", "--plant-model", f"{c}/w3.json"]),
            ("--plant-extra not JSON", ["--plant", "second-generator", "--plant-extra", "{drag: 1}"]),
            ("--plant-extra not an object", ["--plant", "second-generator", "--plant-extra", "[1]"]),
            ("--plant-extra a number", ["--plant", "second-generator", "--plant-extra", "2.0"]),
            ("--plant-extra unknown effect", ["--plant", "second-generator", "--plant-extra", '{"wind": 1}']),
            ("--plant-extra slope angle 0.5", ["--plant", "second-generator", "--plant-extra",
                                                '{"slope": {"angle": 0.5, "direction": 0}}']),
            ("--plant-extra slope without angle", ["--plant", "second-generator", "--plant-extra",
                                                    '{"slope": {"direction": 0}}']),
            ("--plant-extra drag negative", ["--plant", "second-generator", "--plant-extra", '{"drag": -1}']),
            ("--plant-extra drag NaN", ["--plant", "second-generator", "--plant-extra", '{"drag": NaN}']),
            ("--plant-extra drag 1e308", ["--plant", "second-generator", "--plant-extra", '{"drag": 1e308}']),
            ("--plant-extra motor_lag tau 1e308", ["--plant", "second-generator", "--plant-extra",
                                                    '{"motor_lag": {"tau": 1e308}}']),
            ("--plant-extra roller_gap wrong wheel count", ["--plant", "second-generator", "--plant-extra",
                                                             '{"roller_gap": {"phase": [0, 0]}}']),
            ("--plant-extra nested 100000", ["--plant", "second-generator", "--plant-extra", "[" * 100_000]),
            ("--plant-extra without --plant", ["--plant-extra", '{"drag": 1}']),
            ("--plant-model without --plant", ["--plant-model", f"{c}/w3.json"]),
            ("--plant simulator with --plant-extra", ["--plant", "simulator", "--plant-extra", '{"drag": 1}']),
            ("--plant unknown", ["--plant", "real-robot"])):
        add(Case("evaluate --plant", name, [*ev, *argv]))

    # --- export ------------------------------------------------------------------------------------------
    model = ROOT / "agents" / "models" / "ppo-residual"

    def export_case(name: str, policy: Path | str, *argv: str, out_path: str | None = None) -> None:
        add(Case("export", name, ["export", str(policy), "--out", out_path or out("exp"), *argv]))

    export_case("missing model folder", c / "no-model")
    for name, meta in (("meta.json garbage", None), ("meta.json not an object", "[1]"), ("meta.json empty", ""),
                       ("env_id os:system", "envid:os:system"), ("env_id unknown", "envid:Nope-v0"),
                       ("env_id a path", "envid:../../evil:OmniPathFollow-Phunopas-v0"),
                       ("algo unknown", "algo:dqn"), ("obs_mode unknown", "obs_mode:telepathy")):
        d = c / f"exp-model-{len(cases)}"
        shutil.copytree(model, d)
        if meta is None:
            (d / "meta.json").write_bytes(os.urandom(512))
        elif ":" in meta and not meta.startswith("["):
            key, _, value = meta.partition(":")
            key = {"envid": "env_id"}.get(key, key)
            m = json.loads((model / "meta.json").read_text())
            m[key] = value
            (d / "meta.json").write_text(json.dumps(m))
        else:
            (d / "meta.json").write_text(meta)
        export_case(name, d)
    d = c / "exp-no-policy"
    shutil.copytree(model, d)
    (d / "policy.pt").unlink()
    export_case("policy.pt missing", d)
    export_case("a scripted controller (ekf-pid)", "ekf-pid")
    (c / "exp-existing").mkdir()
    (c / "exp-existing" / "policy.onnx").write_text("keep")
    export_case("--out existing without --force", model, out_path=str(c / "exp-existing"))
    export_case("--out an existing file", model, out_path=str(log))
    export_case("--out the model folder itself --force", model, "--force", out_path=str(model))
    export_case("--env unknown", model, "--env", "Nope-v0")
    export_case("--env-kwargs not JSON", model, "--env-kwargs", "{x")
    export_case("--env-kwargs unknown key", model, "--env-kwargs", '{"nope": 1}')

    # --- score, simulate, model show -------------------------------------------------------------------
    _cli("synth", "--model", "regular4", "--hidden", "none", "--runs", "1", "--duration", "1", "--out",
         str(c / "ds4"))
    ds = c / "ds"
    for name, argv in (("--model with 4 wheels on a 3-wheel dataset", ["--model", "regular4"]),
                       ("--model a dataset folder", ["--model", str(ds)]),
                       ("--linear-map-from missing", ["--linear-map-from", f"{c}/none"]),
                       ("--linear-map-from a 4-wheel dataset", ["--linear-map-from", str(c / "ds4")]),
                       ("--linear-map-from without encoders", ["--linear-map-from", str(damaged("lm", drop_enc))]),
                       ("--model the dataset.json", ["--model", str(ds / "dataset.json")])):
        add(Case("score", name, ["score", str(ds), *argv]))
    for name, change in (("runs folder missing", "norun"), ("runs folder empty", "empty"),
                         ("dataset.json missing", "nometa"), ("a run file that is a directory", "dir")):
        d = c / f"score-{len(cases)}"
        shutil.copytree(ds, d)
        if change == "norun":
            shutil.rmtree(d / "runs")
        elif change == "empty":
            for f in (d / "runs").iterdir():
                f.unlink()
        elif change == "nometa":
            (d / "dataset.json").unlink()
        else:
            (d / "runs" / "zz.csv").mkdir()
        add(Case("score", name, ["score", str(d)]))
    cmd = c / "cmd.csv"
    cmd.write_text("t,w1,w2,w3\n0,1,1,1\n0.1,1,1,1\n0.2,0,0,0\n")
    (c / "cmd-3000.csv").write_text("t,w1,w2,w3\n0,3000,3000,3000\n0.1,3000,3000,3000\n0.2,0,0,0\n")
    sim = ["simulate", "--model", wmodel, "--commands", str(cmd)]
    (c / "traj-existing.csv").write_text("keep")
    for name, argv in (("--actuation magic", ["--actuation", "magic", "--out", out("sim")]),
                       ("--seed -1", ["--seed", "-1", "--out", out("sim")]),
                       ("--seed x", ["--seed", "x", "--out", out("sim")]),
                       ("--surface ice", ["--surface", "ice", "--out", out("sim")]),
                       ("--friction magic", ["--friction", "magic", "--out", out("sim")]),
                       ("--out the commands file --force", ["--out", str(cmd), "--force"]),
                       ("--out a directory", ["--out", str(c)]),
                       ("--out existing without --force", ["--out", str(c / "traj-existing.csv")]),
                       ("--dt 1e-9 (too many substeps)", ["--dt", "1e-9", "--out", out("sim")])):
        add(Case("simulate", name, [*sim, *argv]))
    add(Case("simulate", "--out into a missing folder (created, accepted)", [*sim, "--out", f"{c}/new-sim/t.csv"],
             expect="ok"))
    add(Case("simulate", "3000 rad/s, --out into a missing folder (no folder left)",
             ["simulate", "--model", wmodel, "--commands", str(c / "cmd-3000.csv"), "--out", f"{c}/gone-sim/a/t.csv"],
             outside=c / "gone-sim"))
    add(Case("simulate", "--model regular4 with 3-wheel commands", ["simulate", "--model", "regular4", "--commands",
                                                                     str(cmd), "--out", out("sim")]))
    long_cmd = c / "cmd-long.csv"
    long_cmd.write_text("t,w1,w2,w3\n0,1,1,1\n100000,1,1,1\n")
    add(Case("simulate", "a run of 100000 s", ["simulate", "--model", wmodel, "--commands", str(long_cmd), "--out",
                                               out("sim")], time_limit=30.0))
    base = json.loads((c / "w3.json").read_text())
    for name, change in (("unknown key", {"colour": "red"}), ("unknown effect", {"effects": {"wind": {"v": 1}}}),
                         ("effect params a list", {"effects": {"motor_lag": [0.1]}}),
                         ("no wheels", {"wheels": []}), ("one wheel", {"wheels": base["wheels"][:1]})):
        f = c / f"show-{len(cases)}.json"
        f.write_text(json.dumps({**base, **change}))
        add(Case("model show", name, ["model", "show", str(f)]))
    for name, argv in (("--surface ice", ["williams2002", "--surface", "ice"]),
                       ("--friction magic", ["williams2002", "--friction", "magic"]),
                       ("a directory", [str(c)]), ("no name", []), ("regular0", ["regular0"])):
        add(Case("model show", name, ["model", "show", *argv]))

    # --- bad inputs that used to be accepted silently --------------------------------------------------
    silent = "silent accepts"
    head = _edit_csv(log, c / "heading-99999.csv", 5, {"theta": "99999"})
    add(Case(silent, "import csv: a heading of 99999 rad in one row",
             ["import", "csv", str(head), "--model", wmodel, "--columns", columns, "--out", out("head")]))
    d = c / "ds-heading"
    shutil.copytree(ds, d)
    _edit_csv(ds / "runs" / "run000.csv", d / "runs" / "run000.csv", 5, {"theta": "99999"})
    add(Case(silent, "score: a heading of 99999 rad in a run", ["score", str(d)]))
    cmd3000 = c / "cmd-3000.csv"
    add(Case(silent, "simulate: wheel commands of 3000 rad/s", ["simulate", "--model", wmodel, "--commands",
                                                                 str(cmd3000), "--out", out("sim")]))
    add(Case(silent, "synth --noise 5", ["synth", "--model", wmodel, "--hidden", "none", "--runs", "1", "--noise", "5",
                                          "--out", out("syn")]))
    meta_name = next(src.glob("*_metadata.csv")).name
    for name, cells, expect in (("OptiOdom: a row of NaN", lambda v: ["nan"] * 6, "refuse"),
                                ("OptiOdom: a NaN wheel count", lambda v: [*v[:3], "NaN", *v[4:]], "refuse"),
                                ("OptiOdom: a NaN time", None, "refuse"),
                                ("OptiOdom: a NaN pose (tracking dropout, accepted)", lambda v: ["nan"] * 3 + v[3:],
                                 "ok")):
        d = c / f"oo-{len(cases)}" / src.name
        shutil.copytree(src, d)
        f = d / f"{src.name}_run-01.csv"
        lines = f.read_text().splitlines()
        row = lines[50].split(",")
        row = ["nan", *row[1:]] if cells is None else [row[0], *cells(row[1:])]
        lines[50] = ",".join(row)
        f.write_text("\n".join(lines) + "\n")
        assert (d / meta_name).exists()
        add(Case(silent, name, ["import", "optiodom", str(d), "--out", out("oo")], expect=expect))
    return cases


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": str(ROOT), "SDL_VIDEODRIVER": "dummy", "MPLBACKEND": "Agg",
            "OMP_NUM_THREADS": "1"}


def _out_of(argv: list[str]) -> str | None:
    """The value of ``--out`` in ``argv`` (None without one)."""
    return argv[argv.index("--out") + 1] if "--out" in argv[:-1] else None


def run_case(case: Case) -> Case:
    """Run one case in a fresh process, in a fresh empty working folder (a file appearing there is a write
    outside --out), and record what happened in ``case.result``."""
    out = _out_of(case.argv)
    out_before = out is not None and os.path.lexists(out)
    cwd = Path(tempfile.mkdtemp(prefix="omni-gym-probe-cwd-"))
    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, "-m", "omni_gym.cli", *case.argv], cwd=cwd, env={**_env(), **case.env},
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL,
                            start_new_session=True)
    hung = False
    try:
        _, err = proc.communicate(timeout=case.time_limit or TIME_LIMIT_S)
    except subprocess.TimeoutExpired:
        hung = True
        os.killpg(proc.pid, signal.SIGKILL)
        _, err = proc.communicate()
    # peak memory of the process (and its reaped children) [KB]: read from /proc before it was reaped is
    # not possible after communicate, so the probe asks the kernel through wait4 in _rusage below
    err = err.decode(errors="replace")
    control = bool(re.search("[\x00-\x08\x0b-\x1f\x7f]", err))  # an escape sequence reached the terminal
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    in_cwd = sorted(p.name for p in cwd.iterdir())
    shutil.rmtree(cwd, ignore_errors=True)
    case.result = {"rc": proc.returncode, "wall_s": round(time.monotonic() - t0, 2), "stderr": lines[-1][:200]
                   if lines else "", "first": lines[0][:200] if lines else "", "lines": len(lines),
                   "traceback": "Traceback" in err, "hung": hung,
                   "max_rss_kb": _MAXRSS.get(proc.pid, 0), "control": control,
                   "wrote_outside": case.outside is not None and os.path.lexists(case.outside),
                   "replaced_fifo": case.fifo is not None and not case.fifo.is_fifo(),
                   "wrote_cwd": in_cwd[:5],
                   # a refused command leaves no --out behind (complete or absent)
                   "left_out": out is not None and not out_before and proc.returncode != 0 and os.path.lexists(out)}
    return case


_MAXRSS: dict[int, int] = {}


def _install_rss_reaper() -> None:
    """Record each child's peak RSS: subprocess reaps with waitpid, so wrap it to use wait4 instead."""
    original = os.waitpid

    def waitpid(pid: int, options: int):
        if pid > 0:
            wpid, status, usage = os.wait4(pid, options)
            if wpid:
                _MAXRSS[wpid] = int(usage.ru_maxrss)
            return wpid, status
        return original(pid, options)

    os.waitpid = waitpid


def classify(case: Case) -> str:
    r = case.result
    if case.marker is not None and case.marker.exists():
        return "code ran"
    if r.get("wrote_outside") or r.get("replaced_fifo") or r.get("wrote_cwd") or r.get("left_out"):
        return "wrote"
    if r.get("control"):
        return "unescaped"
    if r["hung"]:
        return "hang"
    if r["max_rss_kb"] > MEMORY_LIMIT_KB:
        return "memory"
    if r["traceback"]:
        return "traceback"
    if case.expect == "ok":  # a good input: exit 0, or it was refused
        return "ok as expected" if r["rc"] == 0 else "refused"
    if r["rc"] == 0:
        return "accepted"
    if r["rc"] == 2 and (r["lines"] == 1 and r["stderr"].startswith("omni-gym: error: ")
                         or _USAGE.match(r["stderr"]) and r.get("first", "").startswith("usage:")
                         and r["lines"] <= 40):  # argparse: usage lines, then the error (not a warning first)
        return "clean"
    return "other status"


# argparse's refusal of a malformed option: its usage line(s), then "omni-gym [COMMAND]: error: ..."
_USAGE = re.compile(r"^omni-gym( [a-z]+)*: error: ")
# "ok as expected": a good input accepted; "refused": a good input refused (expect="ok"); "accepted": a bad input
# not refused (a silent accept)
KINDS = ("clean", "ok as expected", "accepted", "refused", "traceback", "other status", "memory", "hang", "code ran",
         "wrote", "unescaped")
GOOD_KINDS = ("clean", "ok as expected")


def subcommand(case: Case) -> str:
    """The subcommand a case runs (``import csv``, ``model show``, ``simulate``; global options skipped)."""
    argv = list(case.argv)
    while argv and argv[0].startswith("--"):
        argv = argv[2:]
    if not argv:
        return "(none)"
    return " ".join(argv[:2]) if argv[0] in ("model", "import") and len(argv) > 1 else argv[0]


def _table(cases: list[Case], key, title: str) -> list[str]:
    groups = sorted({key(c) for c in cases}, key=[key(c) for c in cases].index)
    rows = [f"| {title} | cases | " + " | ".join(KINDS) + " |", "|---|---" + "|---" * len(KINDS) + "|"]
    total = {k: 0 for k in KINDS}
    for g in groups:
        mine = [c for c in cases if key(c) == g]
        counts = {k: sum(classify(c) == k for c in mine) for k in KINDS}
        for k in KINDS:
            total[k] += counts[k]
        rows.append(f"| {g} | {len(mine)} | " + " | ".join(str(counts[k]) for k in KINDS) + " |")
    rows.append(f"| **all** | **{len(cases)}** | " + " | ".join(f"**{total[k]}**" for k in KINDS) + " |")
    return rows


def report(cases: list[Case], wall: float, command: str = "python benchmarks/reliability_probe.py --jobs 2") -> str:
    peak = max(c.result["max_rss_kb"] for c in cases) / 1024
    slow = max(c.result["wall_s"] for c in cases)
    kinds = [classify(c) for c in cases]
    good = sum(k in GOOD_KINDS for k in kinds)
    expected_ok = sum(c.expect == "ok" for c in cases)
    out = ["# Reliability probe: bad inputs on the command line", "",
           f"`{command}` (each case a fresh `python -m omni_gym.cli` process in an empty working folder; "
           f"{wall:.0f} s on the shared 2-core machine). Clean: exit status 2, one line `omni-gym: error: …`, no "
           "traceback, peak memory under 1 GB, no hang, for crafted models no payload run, nothing written outside "
           "`--out` (the working folder stays empty, a refused command leaves no `--out`). "
           f"{expected_ok} cases are good inputs that must be accepted (`ok as expected`: exit 0). "
           f"Clean outcomes: {good} of {len(cases)} ({100.0 * good / len(cases):.1f} %); writes outside --out: "
           f"{kinds.count('wrote')}; silent accepts: {kinds.count('accepted')}. "
           f"Peak memory of any case: {peak:.0f} MB; slowest case: {slow:.1f} s.", "",
           "## Per category", "", *_table(cases, lambda c: c.category, "category"), "",
           "## Per subcommand", "", *_table(cases, subcommand, "subcommand"), ""]
    bad = [c for c in cases if classify(c) not in GOOD_KINDS]
    if bad:
        out += ["## Cases that were not clean", "", "| category | case | kind | status | last line |",
                "|---|---|---|---|---|"]
        for c in bad:
            line = c.result["stderr"].replace("|", "\\|")
            out.append(f"| {c.category} | {c.name} | {classify(c)} | {c.result['rc']} | {line} |")
        out.append("")
    return "\n".join(out)


# Each builder and the categories of its cases (``--only`` builds only the builders it can match).
CATEGORIES = {
    "build_cases": ("commands CSV", "model JSON", "dataset", "OptiOdom import", "evaluate", "train --hyperparams",
                    "synth", "gap options", "global options"),
    "build_command_cases": ("import csv", "import rosbag2", "calibrate", "evaluate --plant", "export", "score",
                            "simulate", "model show", "silent accepts"),
    "build_hostile_cases": ("hostile: run names", "hostile: damaged files", "hostile: messages", "hostile: --force",
                            "hostile: model folders", "hostile: train sizes"),
}


def build_all(work: Path, only: str | None = None) -> list[Case]:
    """Every case (or those of the categories containing ``only``), built under ``work``."""
    cases: list[Case] = []
    for name, categories in CATEGORIES.items():
        if only is None or any(only in cat for cat in categories):
            cases += globals()[name](work)
    return [c for c in cases if only is None or only in c.category]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2, help="cases run at once")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "reliability_probe.md"),
                    help="the markdown table to write (a folder: reliability_probe.md in it)")
    ap.add_argument("--only", default=None, help="run only the categories whose name contains this")
    ap.add_argument("--dump", default=None, help="also write every case's result as JSON lines to this file")
    given = sys.argv[1:] if argv is None else list(argv)
    args = ap.parse_args(given)
    command = shlex.join(["python", "benchmarks/reliability_probe.py", *given])
    target = Path(args.out) / "reliability_probe.md" if Path(args.out).is_dir() else Path(args.out)
    _install_rss_reaper()
    with tempfile.TemporaryDirectory(prefix="omni-gym-probe-") as tmp:
        cases = build_all(Path(tmp), args.only)
        print(f"{len(cases)} cases", flush=True)
        t0 = time.monotonic()
        with ThreadPoolExecutor(args.jobs) as pool:
            for i, c in enumerate(pool.map(run_case, cases)):
                kind = classify(c)
                if kind not in GOOD_KINDS:
                    print(f"[{i + 1}/{len(cases)}] {c.category} / {c.name}: {kind}: {c.result['stderr']}", flush=True)
        text = report(cases, time.monotonic() - t0, command)
        if args.dump:
            with open(args.dump, "w") as fh:
                for c in cases:
                    fh.write(json.dumps({"category": c.category, "name": c.name, "argv": c.argv[:12],
                                         "expect": c.expect, "kind": classify(c), **c.result}) + "\n")
    target.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
