import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("MPLBACKEND", "Agg")

import pytest  # noqa: E402


@pytest.fixture(scope="module")
def ray_cluster():
    """A local Ray cluster on 127.0.0.1 with 2 CPUs, started for the module's tests and stopped after.

    Yields the address other processes (``--ray ADDRESS``, ``--address ADDRESS``) connect to. Ray is a
    dev dependency (the ``rllib`` extra): a missing ray is an install defect, so it fails, never skips.
    """
    import ray

    ray.init(num_cpus=2, include_dashboard=False, _node_ip_address="127.0.0.1", log_to_driver=False,
             configure_logging=False)
    try:
        yield ray.get_runtime_context().gcs_address
    finally:
        ray.shutdown()
