"""Worker processes pin numba to one thread without breaking numba's next compilation.

numba reads ``NUMBA_NUM_THREADS`` when it is imported (default: the machine's cores) and again at every
compilation, raising "Cannot set NUMBA_NUM_THREADS to a different value once the threads have been
launched" when the value changed after its thread pool started. ``gap --jobs 16`` on a 16-core machine
met it: a worker imported numba while unpickling its shared input (default 16 threads), then pinned
``NUMBA_NUM_THREADS=1`` and started the pool, and the first compilation (a fresh machine: no cached
kernel) failed. On this 2-core machine the same happens with the environment of a large machine
(``NUMBA_NUM_THREADS=16`` inherited, as numba's default would be there) and an empty numba cache.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# A task module the workers import: numba at its top (as omni_gym's physics is for gap's shared input),
# a cached kernel that a cold cache compiles in the worker, and a shared input whose unpickling imports it.
TASK_MODULE = textwrap.dedent('''
    import numba

    @numba.njit(cache=True)
    def _kernel(x):
        return 2.0 * x + 1.0

    class Shared:
        """The workers' shared input: unpickling it imports this module, hence numba."""
        offset = 10.0

    def task(shared, x):
        return float(_kernel(float(x))) + shared.offset
''')

DRIVER = textwrap.dedent('''
    from numba_task import Shared, task
    from omni_gym.parallel import Backend, parallel_map
    print(parallel_map(task, [1, 2, 3, 4], Backend(jobs=2), shared=Shared()))
''')

PINNED_AFTER_IMPORT = textwrap.dedent('''
    import numba
    from omni_gym.parallel import pin_threads
    pin_threads()  # numba is loaded already (a Ray worker: the task's arguments import it)
    kernel = numba.njit(lambda x: x + 1)
    print(kernel(1), numba.get_num_threads())
''')


def _run(code: str, tmp_path: Path, **env: str) -> subprocess.CompletedProcess:
    (tmp_path / "numba_task.py").write_text(TASK_MODULE)
    cache = tmp_path / "numba_cache"  # empty: every kernel is compiled, as on a fresh machine
    cache.mkdir(exist_ok=True)
    full = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)]), "NUMBA_CACHE_DIR": str(cache),
            **env}
    return subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=full, capture_output=True, text=True,
                          timeout=120)


def test_workers_compile_on_a_cold_cache_with_a_large_machines_thread_count(tmp_path):
    out = _run(DRIVER, tmp_path, NUMBA_NUM_THREADS="16")
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.split("\n")[0] == "[13.0, 15.0, 17.0, 19.0]"  # 2x + 1 + 10, in the order of the arguments


def test_pinning_after_numba_is_loaded_keeps_compilation_working(tmp_path):
    out = _run(PINNED_AFTER_IMPORT, tmp_path, NUMBA_NUM_THREADS="4")  # any count above 1: numba loads with it
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.split() == ["2", "1"]  # the kernel compiled and ran; one thread runs
