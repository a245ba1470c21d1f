"""The reliability probe's cases (benchmarks/reliability_probe.py): enough of them, every category built, and a
few of the command-line cases run clean through the probe's own runner (the whole probe takes minutes)."""

from __future__ import annotations

import pytest
from benchmark_loader import load_benchmark

rp = load_benchmark("reliability_probe")

# One case per subcommand among those added with the per-subcommand builder, each a refusal (or, for the CSV with
# a byte-order mark, an acceptance) that must stay clean.
SAMPLE = (
    ("import csv", "BOM and CRLF line ends (accepted)"),
    ("import csv", "unit mistake: joint angles read as rpm (--units wheel=rpm)"),
    ("import csv", "--columns four wheels of three"),
    ("calibrate", "a slipping robot on carpet (values at bounds)"),
    ("calibrate", "--out into a missing folder, refused (no folder left)"),
    ("evaluate --plant", "--plant-extra slope angle 0.5"),
    ("export", "--out existing without --force"),
    ("silent accepts", "synth --noise 5"),
    ("silent accepts", "simulate: wheel commands of 3000 rad/s"),
    ("silent accepts", "OptiOdom: a row of NaN"),
)


@pytest.fixture(scope="module")
def cases(tmp_path_factory):
    return rp.build_all(tmp_path_factory.mktemp("probe"))


def test_case_count_and_categories(cases):
    assert len(cases) >= 660
    declared = {cat: name for name, cats in rp.CATEGORIES.items() for cat in cats}
    built = {c.category for c in cases}
    assert built <= set(declared), built - set(declared)  # every case's category belongs to a builder
    assert set(declared) <= built, set(declared) - built  # every declared category has cases
    assert all(c.expect in ("refuse", "ok") for c in cases)
    assert sum(c.expect == "ok" for c in cases) >= 5  # good inputs that must be accepted, counted apart
    names = [(c.category, c.name) for c in cases]
    assert len(names) == len(set(names)), "two cases of one name in one category"


def test_only_builds_the_matching_builder(tmp_path):
    only = rp.build_all(tmp_path, "evaluate --plant")
    assert only and {c.category for c in only} == {"evaluate --plant"}


def test_sample_of_new_cases_runs_clean(cases):
    by_name = {(c.category, c.name): c for c in cases}
    missing = [key for key in SAMPLE if key not in by_name]
    assert not missing, missing
    for key in SAMPLE:
        case = rp.run_case(by_name[key])
        kind = rp.classify(case)
        assert kind in rp.GOOD_KINDS, (key, kind, case.result)
        assert kind == ("ok as expected" if case.expect == "ok" else "clean")


def test_classify_kinds():
    def case(expect="refuse", **result):
        c = rp.Case("x", "y", ["model", "show", "x"], expect=expect)
        c.result = {"rc": 2, "lines": 1, "stderr": "omni-gym: error: bad", "first": "omni-gym: error: bad",
                    "traceback": False, "hung": False, "max_rss_kb": 0, "control": False, "wrote_outside": False,
                    "replaced_fifo": False, "wrote_cwd": [], "left_out": False, **result}
        return c

    assert rp.classify(case()) == "clean"
    assert rp.classify(case(rc=0)) == "accepted"
    assert rp.classify(case("ok", rc=0)) == "ok as expected"
    assert rp.classify(case("ok")) == "refused"
    assert rp.classify(case(wrote_cwd=["x.csv"])) == "wrote"
    assert rp.classify(case(left_out=True)) == "wrote"
    assert rp.subcommand(rp.Case("x", "y", ["--max-input-mb", "1", "import", "csv", "f"])) == "import csv"
    assert rp.subcommand(rp.Case("x", "y", ["simulate", "--model", "m"])) == "simulate"
