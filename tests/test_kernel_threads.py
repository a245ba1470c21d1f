"""Item 7 of issue 14: importing omni_gym sets no OpenMP variable; the threaded kernel sets it for itself."""

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


def test_omp_wait_policy_is_passive_for_the_kernel_threads_only() -> None:
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    env |= {"OMP_DISPLAY_ENV": "TRUE", "OMP_NUM_THREADS": "2"}  # libgomp prints its settings when it starts
    out = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, timeout=300,
                         check=True)
    assert "import: None" in out.stdout  # importing the package changed nothing
    assert "after: None" in out.stdout  # and the variable is restored once the threads run
    assert "OMP_WAIT_POLICY = 'PASSIVE'" in out.stderr  # yet numba's libgomp started with passive waiting


def test_a_users_omp_wait_policy_is_kept() -> None:
    env = {**os.environ, "OMP_WAIT_POLICY": "ACTIVE", "OMP_DISPLAY_ENV": "TRUE", "OMP_NUM_THREADS": "2"}
    out = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, timeout=300,
                         check=True)
    assert "after: ACTIVE" in out.stdout
    assert "OMP_WAIT_POLICY = 'ACTIVE'" in out.stderr
