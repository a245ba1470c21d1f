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


@pytest.fixture(scope="module")
def omni3_two_runs(tmp_path_factory):
    """Runs 1 and 2 of the bundled omni3 session circular/221220201730, imported (``omni-gym calibrate`` accepts
    them: tests/test_calibrate_cli.py)."""
    import shutil
    from pathlib import Path

    from omni_gym.discrepancy.data.importers.optiodom import import_optiodom

    session = Path(__file__).resolve().parents[1] / "data" / "optiodom-omni3" / "circular" / "221220201730"
    root = tmp_path_factory.mktemp("omni3")
    folder = root / "session"
    folder.mkdir()
    shutil.copy(session / "221220201730_metadata.csv", folder)
    for k in (1, 2):
        shutil.copy(session / f"221220201730_run-0{k}.csv", folder)
    import_optiodom([folder], root / "ds")
    return root / "ds"


@pytest.fixture(scope="module")
def lag_dataset(tmp_path_factory):
    """A small synthetic dataset with a hidden motor lag (τ 80 ms; 3 runs of 1.5 s, tracker noise 1 mm, seed 5)."""
    from omni_gym.discrepancy.synthetic.recovery import nominal_model
    from omni_gym.discrepancy.synthetic.synth import write_synthetic

    folder = tmp_path_factory.mktemp("lag") / "lag"
    write_synthetic(folder, nominal_model(), 'motor_lag:{"tau": 0.08}', 3, 0.001, 5, 1.5)
    return folder


@pytest.fixture
def only_motor_lag(monkeypatch):
    """Fit only the motor_lag candidate (fast); the decision rules are unchanged."""
    from omni_gym.discrepancy import workflow
    from omni_gym.discrepancy.fit import candidates

    monkeypatch.setattr(workflow, "candidates",
                        lambda model: [c for c in candidates.candidates(model) if c.name == "motor_lag"])
