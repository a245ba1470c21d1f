"""benchmarks/rl_vs_baselines.py's episode cache: a retrained model at the same path is evaluated again."""

from __future__ import annotations

from pathlib import Path

from benchmark_loader import load_benchmark

ROOT = Path(__file__).resolve().parents[1]


def _load():
    return load_benchmark("rl_vs_baselines")


def test_cache_key_changes_when_the_model_files_change(tmp_path):
    rvb = _load()
    model = tmp_path / "ppo-x"
    model.mkdir()
    (model / "model.zip").write_bytes(b"first weights")
    (model / "meta.json").write_text("{}")
    batch = rvb.Batch("OmniPathFollow-Phunopas-v0", str(model), "held-out", "slip", None, (1,), ())
    before = batch.cache_key(1)
    assert batch.cache_key(1) == before  # stable while the files are unchanged
    (model / "model.zip").write_bytes(b"retrained weights")
    rvb.policy_fingerprint.cache_clear()  # one benchmark run hashes each model once
    assert batch.cache_key(1) != before
    scripted = rvb.Batch("OmniPathFollow-Phunopas-v0", "ekf-pid", "held-out", "slip", None, (1,), ())
    assert '"ekf-pid", "ekf-pid"' in scripted.cache_key(1)  # scripted policies: their name is their identity
