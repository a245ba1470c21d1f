"""Reliability probe: bad inputs on the command line, each in a fresh ``omni-gym`` process.

    python benchmarks/reliability_probe.py [--jobs 2] [--out benchmarks/results/reliability_probe.md]

Every case is an input a user could give by mistake or an attacker on purpose: malformed and absurd
files (commands CSV, model JSON, dataset, OptiOdom logs, hyperparameter YAML), special files
(``/dev/zero``, a pipe), oversized inputs, crafted models (pickles with a payload, ``meta.json`` paths
leading out of the folder), bad options. A case is **clean** when the process exits with status 2
and prints exactly one line ``omni-gym: error: ...`` (no traceback), its peak resident memory stays
under 1 GB and it ends within the case's time limit (argparse's refusal of a malformed option, its usage
line then ``omni-gym COMMAND: error: ...``, counts as clean too); a crafted model must also leave its payload's
marker file absent. Anything else is counted by kind: ``accepted`` (exit 0: the bad input was not
refused), ``traceback``, ``other status`` (also a warning printed before the error line), ``memory``, ``hang``,
``code ran``, ``wrote`` (a file outside ``--out``, or ``--force`` replaced a FIFO) and ``unescaped`` (a control
character, e.g. an escape sequence from a crafted file, reached the terminal).

``--only hostile`` runs just the hostile-input cases (:func:`build_hostile_cases`), in about half a minute.

The table (counts per category and kind, then every case that was not clean) goes to ``--out``.
"""

from __future__ import annotations

import argparse
import base64
import gzip
import json
import os
import pickle
import re
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
        add(Case("evaluate", f"crafted SB3 zip ({algo})", ["evaluate", "--policy", str(z), "--algo", algo, *extra,
                                                             *ev[1:]], marker=marker))
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


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": str(ROOT), "SDL_VIDEODRIVER": "dummy", "MPLBACKEND": "Agg",
            "OMP_NUM_THREADS": "1"}


def run_case(case: Case) -> Case:
    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, "-m", "omni_gym.cli", *case.argv], cwd=ROOT, env={**_env(), **case.env},
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
    case.result = {"rc": proc.returncode, "wall_s": round(time.monotonic() - t0, 2), "stderr": lines[-1][:200]
                   if lines else "", "first": lines[0][:200] if lines else "", "lines": len(lines),
                   "traceback": "Traceback" in err, "hung": hung,
                   "max_rss_kb": _MAXRSS.get(proc.pid, 0), "control": control,
                   "wrote_outside": case.outside is not None and os.path.lexists(case.outside),
                   "replaced_fifo": case.fifo is not None and not case.fifo.is_fifo()}
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
    if r.get("wrote_outside") or r.get("replaced_fifo"):
        return "wrote"
    if r.get("control"):
        return "unescaped"
    if r["hung"]:
        return "hang"
    if r["max_rss_kb"] > MEMORY_LIMIT_KB:
        return "memory"
    if r["traceback"]:
        return "traceback"
    if r["rc"] == 0:
        return "accepted"
    if r["rc"] == 2 and (r["lines"] == 1 and r["stderr"].startswith("omni-gym: error: ")
                         or _USAGE.match(r["stderr"]) and r.get("first", "").startswith("usage:")
                         and r["lines"] <= 40):  # argparse: usage lines, then the error (not a warning first)
        return "clean"
    return "other status"


# argparse's refusal of a malformed option: its usage line(s), then "omni-gym [COMMAND]: error: ..."
_USAGE = re.compile(r"^omni-gym( [a-z]+)*: error: ")
KINDS = ("clean", "accepted", "traceback", "other status", "memory", "hang", "code ran", "wrote", "unescaped")


def report(cases: list[Case], wall: float) -> str:
    cats = sorted({c.category for c in cases}, key=[c.category for c in cases].index)
    rows = ["| category | cases | " + " | ".join(KINDS) + " |", "|---|---" + "|---" * len(KINDS) + "|"]
    total = {k: 0 for k in KINDS}
    for cat in cats:
        mine = [c for c in cases if c.category == cat]
        counts = {k: sum(classify(c) == k for c in mine) for k in KINDS}
        for k in KINDS:
            total[k] += counts[k]
        rows.append(f"| {cat} | {len(mine)} | " + " | ".join(str(counts[k]) for k in KINDS) + " |")
    rows.append(f"| **all** | **{len(cases)}** | " + " | ".join(f"**{total[k]}**" for k in KINDS) + " |")
    peak = max(c.result["max_rss_kb"] for c in cases) / 1024
    slow = max(c.result["wall_s"] for c in cases)
    out = ["# Reliability probe: bad inputs on the command line", "",
           "`python benchmarks/reliability_probe.py --jobs 2` (each case a fresh `python -m omni_gym.cli` process; "
           f"{wall:.0f} s on the shared 2-core machine). Clean: exit status 2, one line `omni-gym: error: …`, no "
           "traceback, peak memory under 1 GB, no hang, and for crafted models no payload run. "
           f"Peak memory of any case: {peak:.0f} MB; slowest case: {slow:.1f} s.", "", *rows, ""]
    bad = [c for c in cases if classify(c) != "clean"]
    if bad:
        out += ["## Cases that were not clean", "", "| category | case | kind | status | last line |",
                "|---|---|---|---|---|"]
        for c in bad:
            line = c.result["stderr"].replace("|", "\\|")
            out.append(f"| {c.category} | {c.name} | {classify(c)} | {c.result['rc']} | {line} |")
        out.append("")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2, help="cases run at once")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "reliability_probe.md"))
    ap.add_argument("--only", default=None, help="run only the categories whose name contains this")
    ap.add_argument("--dump", default=None, help="also write every case's result as JSON lines to this file")
    args = ap.parse_args(argv)
    _install_rss_reaper()
    with tempfile.TemporaryDirectory(prefix="omni-gym-probe-") as tmp:
        hostile_only = bool(args.only) and args.only.startswith("hostile")
        cases = ([] if hostile_only else build_cases(Path(tmp))) + build_hostile_cases(Path(tmp))
        if args.only:
            cases = [c for c in cases if args.only in c.category]
        print(f"{len(cases)} cases", flush=True)
        t0 = time.monotonic()
        with ThreadPoolExecutor(args.jobs) as pool:
            for i, c in enumerate(pool.map(run_case, cases)):
                kind = classify(c)
                if kind != "clean":
                    print(f"[{i + 1}/{len(cases)}] {c.category} / {c.name}: {kind}: {c.result['stderr']}", flush=True)
        text = report(cases, time.monotonic() - t0)
        if args.dump:
            with open(args.dump, "w") as fh:
                for c in cases:
                    fh.write(json.dumps({"category": c.category, "name": c.name, "argv": c.argv[:12],
                                         "kind": classify(c), **c.result}) + "\n")
    Path(args.out).write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
