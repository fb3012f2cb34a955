"""prb_report_once: the PRB synthesis made once per process for the same arguments (the
constant-force report's, made by the run's report thread while the workers solve)."""

import numpy as np
from flexopt.fea import prb


def test_made_once_per_arguments_and_equal_to_prb_report(monkeypatch):
    monkeypatch.setattr(prb, "_REPORTS", {})
    calls = []
    real = prb.optimise_prb

    def counted(*args, **kwargs):
        calls.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(prb, "optimise_prb", counted)
    first = prb.prb_report_once(1.5, 30.0, 1800.0, 42.5, 0.8)
    again = prb.prb_report_once(1.5, 30, 1800, 42.5, 0.8)  # the same arguments as numbers
    assert len(calls) == 1
    direct = prb.prb_report(1.5, 30.0, 1800.0, 42.5, 0.8)
    assert len(calls) == 2
    for key in direct:
        if key != "time_s":  # the first call's
            assert first[key] == direct[key] == again[key], key
    # other arguments: made again
    other = prb.prb_report_once(2.0, 30.0, 1800.0, 42.5, 0.8)
    assert len(calls) == 3
    assert other["target_force_N"] == 2.0 and not np.isclose(other["r1_mm"], 0.0)


def test_each_call_gets_its_own_copy(monkeypatch):
    monkeypatch.setattr(prb, "_REPORTS", {})
    first = prb.prb_report_once(1.5, 30.0)
    first["lumped_flexures"]["width_mm"].append(-1.0)
    first["r1_mm"] = None
    again = prb.prb_report_once(1.5, 30.0)
    assert again["r1_mm"] is not None
    assert -1.0 not in again["lumped_flexures"]["width_mm"]
