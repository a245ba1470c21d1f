"""Can the scripted controller do the custom id's task on a nominal robot? Reachable references, measured.

For the nominal model of every robot preset (on its id's floor, and the williams2002 robot also on carpet with
the ``initial`` friction model, the case that failed) and of both bundled real robots (``omni-gym import
optiodom``'s nominal models, on the ``grip`` floor their import assumes), ``ekf-pid`` runs 50 held-out episodes
(seeds 10000–10049) on ``OmniPathFollow-Custom-v0``:

* **reachable** (the id's defaults: waypoints turning in place, ``ref_traction`` 0.15);
* **as drawn** (``ref_turn="during"``, ``ref_traction=0``: the custom id's former task);

and on the id made for that robot with its own defaults (williams2002: ``OmniPathFollow-Williams-v1``;
phunopas2018: ``OmniPathFollow-Phunopas-v0``; optiodom_omni4: ``OmniPathFollow-Mecanum-v0``; these ids have
lift-off where the nominal models have none). The goal: the goal reached in ≥ 95 % of the episodes and a
tracking RMSE within 2× the id's.

    python benchmarks/feasible_tasks.py --out benchmarks/results [--episodes 50]

Writes OUT/feasible_tasks.md. Batched rollouts (``agents.vector_rollout``, the batched ``ekf-pid``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from agents.evaluate import wilson_ci  # noqa: E402
from omni_gym.envs import CUSTOM_ID  # noqa: E402
from omni_gym.physics.model import load_model  # noqa: E402
from omni_gym.record_paths import record_args  # noqa: E402

FIRST_SEED = 10_000
AS_DRAWN = {"ref_turn": "during", "ref_traction": 0.0}
# (label, how the nominal model is made, the id made for that robot or None)
ROBOTS = (
    ("williams2002, carpet, initial", ("preset", "williams2002", "carpet", "initial"), "OmniPathFollow-Williams-v1"),
    ("williams2002, carpet, roller_gap", ("preset", "williams2002", "carpet", "roller_gap"),
     "OmniPathFollow-Williams-v1"),
    ("phunopas2018, carpet, roller_gap", ("preset", "phunopas2018", "carpet", "roller_gap"),
     "OmniPathFollow-Phunopas-v0"),
    ("optiodom_omni4, carpet, initial", ("preset", "optiodom_omni4", "carpet", "initial"),
     "OmniPathFollow-Mecanum-v0"),
    ("optiodom_omni3, grip, initial", ("preset", "optiodom_omni3", "grip", "initial"), None),
    ("real omni3 (OptiOdom import)", ("optiodom", "data/optiodom-omni3/circular/221220201643"), None),
    ("real omni4 (OptiOdom import)", ("optiodom", "data/optiodom-omni4/circular/080920201015"),
     "OmniPathFollow-Mecanum-v0"),
)


def nominal_model(how: tuple, tmp: Path) -> dict:
    """The nominal model JSON: a preset on a floor, or what ``omni-gym import optiodom`` writes for a session."""
    if how[0] == "preset":
        _, robot, surface, friction = how
        return load_model(robot, surface=surface, friction=friction).to_json()
    out = tmp / "ds"
    proc = subprocess.run([sys.executable, "-m", "omni_gym.cli", "import", "optiodom", str(ROOT / how[1]), "--out",
                           str(out), "--force"], capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr.strip())
    return json.loads((out / "dataset.json").read_text())["model"]


def episodes(env_id: str, kwargs: dict, n: int) -> dict:
    """ekf-pid's held-out episodes on ``env_id`` (batched): RMSE [m] per episode and the successes."""
    import gymnasium as gym

    import omni_gym  # noqa: F401
    from agents.batched.policies import make_vector_policy
    from agents.vector_rollout import run_episodes_vector

    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", autoreset_mode="next_step",
                        max_episode_steps=None, obs_mode="sensors", action_mode="twist", **kwargs)
    try:
        eps = run_episodes_vector(venv, make_vector_policy("ekf-pid", venv), list(range(FIRST_SEED, FIRST_SEED + n)))
        use = venv.unwrapped.core.ref_use.copy()  # the references of the episodes just run (first reset)
    finally:
        venv.close()
    return {"rmse": [e.tracking_rmse for e in eps], "success": [bool(e.success) for e in eps],
            "max_use": float(np.nanmax(use)) if np.isfinite(use).any() else None}


INTRO = ("`ekf-pid` (batched), {n} held-out episodes (seeds {first}…) of 20 s. Goal reached: within 5 cm and "
         "0.1 rad at the end, not lost (95 % Wilson interval). *÷ id*: mean RMSE ÷ the same controller's on the id "
         "made for that robot (its own defaults, with lift-off where the id has it). *peak use*: the largest share of "
         "the wheels' friction set any episode's reference asks for (`info[\"reference_traction\"]`).")


def row(label: str, res: dict, ref: dict | None) -> str:
    rm = 1e3 * np.mean(res["rmse"])
    k, n = sum(res["success"]), len(res["success"])
    lo, hi = wilson_ci(k, n)
    ratio = "–" if ref is None else f"{np.mean(res['rmse']) / np.mean(ref['rmse']):.2f}"
    use = "–" if res["max_use"] is None else f"{res['max_use']:.2f}"
    return f"| {label} | {rm:.2f} | {k}/{n} ({100 * k / n:.0f} %) [{100 * lo:.0f}, {100 * hi:.0f}] | {ratio} | {use} |"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    command = "python benchmarks/feasible_tasks.py " + " ".join(record_args(argv if argv is not None else sys.argv[1:]))
    lines = ["# Reachable references: ekf-pid on the custom id with nominal robots", "", f"`{command}`", "",
             INTRO.format(n=args.episodes, first=FIRST_SEED), "",
             "| robot (nominal model) · task | RMSE [mm] | goal reached | ÷ id | peak use |", "|---|---|---|---|---|"]
    verdicts = []
    with tempfile.TemporaryDirectory() as tmp:
        for label, how, env_id in ROBOTS:
            model = nominal_model(how, Path(tmp))
            path = Path(tmp) / "model.json"
            path.write_text(json.dumps(model))
            ref = episodes(env_id, {}, args.episodes) if env_id else None
            reach = episodes(CUSTOM_ID, {"model": str(path)}, args.episodes)
            drawn = episodes(CUSTOM_ID, {"model": str(path), **AS_DRAWN}, args.episodes)
            lines.append(row(f"{label} · **reachable** (the custom id's defaults)", reach, ref))
            lines.append(row(f"{label} · as drawn (`ref_turn=\"during\"`, `ref_traction=0`)", drawn, ref))
            if ref is not None:
                lines.append(row(f"{label} · on `{env_id}`", ref, ref))
            share = float(np.mean(reach["success"]))
            times = None if ref is None else float(np.mean(reach["rmse"]) / np.mean(ref["rmse"]))
            ok = share >= 0.95 and (times is None or times <= 2.0)
            verdicts.append(f"- {label}: {'**met**' if ok else '**missed**'} (goal in {100 * share:.0f} %"
                            + ("" if times is None else f", {times:.2f}× the id's RMSE") + ")")
            print(lines[-2 if ref is None else -3], file=sys.stderr, flush=True)
    lines += ["", "Goal (≥ 95 % of the episodes reach the goal, RMSE ≤ 2× the id's) on the reachable task:", "",
              *verdicts, "", f"Wall time {(time.perf_counter() - t0) / 60:.1f} min."]
    text = "\n".join(lines) + "\n"
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "feasible_tasks.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
