"""report.md's performance table names the hybrid's checks by the verdict's figures (run.json
``hybrid.checks``) where the run made any, and nothing otherwise."""

from __future__ import annotations

from flexopt.pipeline.report import _checks_row


def test_a_hybrid_run_with_checks_gets_a_row():
    record = {"hybrid": {"checks": {"count": 3, "met": 2, "time_s": 7.5, "best_verified": True}}}
    ((label, value),) = _checks_row(record)
    assert "checks" in label
    assert value == "3 designs (2 met), 7.5 s"
    record["hybrid"]["checks"].update(count=1, met=1, spared=1)
    ((_, value),) = _checks_row(record)
    assert value == "1 design (1 met), 7.5 s; 1 start not checked (a lower design was met)"


def test_no_row_without_checks():
    assert _checks_row({}) == []
    assert _checks_row({"hybrid": {"method": "hybrid"}}) == []
    assert _checks_row({"hybrid": None}) == []
