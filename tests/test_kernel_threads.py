"""The threaded kernel's OpenMP threads wait passively; a user's OMP_WAIT_POLICY is kept.

Importing omni_gym sets OMP_WAIT_POLICY=PASSIVE unless the user set it (why: omni_gym/__init__.py).
"""

from __future__ import annotations

import os
import subprocess
import sys

CHILD = """
import os
import omni_gym
print("import:", os.environ.get("OMP_WAIT_POLICY"))
from omni_gym.physics.kernel import substep_parallel, warm_up
warm_up(substep_parallel)
print("after:", os.environ.get("OMP_WAIT_POLICY"))
"""


def test_omp_wait_policy_is_passive_by_default() -> None:
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    env |= {"OMP_DISPLAY_ENV": "TRUE", "OMP_NUM_THREADS": "2"}  # libgomp prints its settings when it starts
    out = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, timeout=300,
                         check=True)
    assert "import: PASSIVE" in out.stdout  # the default is set at import (see omni_gym/__init__.py)
    assert "after: PASSIVE" in out.stdout
    assert "OMP_WAIT_POLICY = 'PASSIVE'" in out.stderr  # numba's libgomp started with passive waiting


def test_a_users_omp_wait_policy_is_kept() -> None:
    env = {**os.environ, "OMP_WAIT_POLICY": "ACTIVE", "OMP_DISPLAY_ENV": "TRUE", "OMP_NUM_THREADS": "2"}
    out = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, timeout=300,
                         check=True)
    assert "after: ACTIVE" in out.stdout
    assert "OMP_WAIT_POLICY = 'ACTIVE'" in out.stderr
