#!/usr/bin/env bash
# Non-editable install check: build a wheel, install it with the agents extra into a
# fresh virtualenv, and from a directory outside the repository (so the source tree is not importable)
# run `omni-gym --version`, a short `omni-gym train` and an `omni-gym evaluate` of the result.
# Usage: .ci/install_check.sh   (from anywhere; uses python3 from PATH for the new venv)
set -euo pipefail
REPO="$(cd "$(dirname "$0")/.." && pwd)"
WORK="$(mktemp -d "${TMPDIR:-/tmp}/omni-gym-install-check.XXXXXX")"
trap 'rm -rf "$WORK"' EXIT
export SDL_VIDEODRIVER=dummy MPLBACKEND=Agg
start=$(date +%s)

# 1. The wheel, from a copy of the sources: building in the tree would write build/ into it.
mkdir -p "$WORK/src"
cp "$REPO/pyproject.toml" "$REPO/README.md" "$WORK/src/"
for pkg in omni_gym agents; do
    (cd "$REPO" && tar --exclude=__pycache__ --exclude='*.pyc' --exclude='agents/models' -cf - "$pkg") \
        | tar -xf - -C "$WORK/src"
done
python3 -m venv "$WORK/venv"
PY="$WORK/venv/bin/python"
"$PY" -m pip install -q --upgrade "setuptools>=68" wheel
"$PY" -m pip wheel -q --no-deps --no-build-isolation "$WORK/src" -w "$WORK/dist"
WHEEL="$(ls "$WORK"/dist/omni_gym-*.whl)"
echo "install-check: built $(basename "$WHEEL")"

# 2. Non-editable install with the agents extra; torch pinned to the CPU build (never a CUDA download).
"$PY" -m pip install -q -c "$REPO/constraints.txt" "${WHEEL}[agents]"

# 3. From outside the repository.
mkdir -p "$WORK/run"
cd "$WORK/run"
"$PY" -c "import omni_gym, sys; p = omni_gym.__file__; sys.exit(0 if '$REPO' not in p else 'imported from the source tree: ' + p)"
"$WORK/venv/bin/omni-gym" --version
"$WORK/venv/bin/omni-gym" train --algo ppo --env OmniPathFollow-Phunopas-v0 --hyperparams ppo_residual --timesteps 256 --n-envs 1 \
    --eval-freq 0 --seed 0 --out "$WORK/run/model" --no-progress
for f in model.zip final_model.zip vecnormalize.pkl meta.json; do
    test -s "$WORK/run/model/$f" || { echo "install-check: model/$f missing" >&2; exit 1; }
done
"$WORK/venv/bin/omni-gym" evaluate --policy "$WORK/run/model" --env OmniPathFollow-Phunopas-v0 --episodes 1 \
    --seed 0 --env-kwargs '{"episode_seconds": 1.0}' > /dev/null
echo "install-check: passed in $(( $(date +%s) - start )) s"
