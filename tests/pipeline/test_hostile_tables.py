"""Hostile target-table files (issue 23, class 3): ``target: {kind: table, file: ...}``.

The corpus is generated here: files in odd encodings, a field far over the csv module's limit,
files of 300 MB and 1 GB (sparse: they cost no disk), ``/dev/zero``, a FIFO, a folder, and files
whose first line is a secret. ``flexopt evaluate`` and ``flexopt run`` must refuse each with exit
2 and one line naming the key, no traceback, nothing written, an existing run folder unchanged,
nothing solved (how quickly: benchmarks/refusals.py); and no error may echo a byte of the file.
"""

from __future__ import annotations

import codecs
import os
from pathlib import Path

import flexopt_toys
import numpy as np
import pytest
from flexopt.pipeline.cli import main
from flexopt.pipeline.parallel import ParallelSettings
from flexopt.pipeline.run import prepare_run, run_study
from flexopt.pipeline.study import load_study, validate_study
from flexopt.pipeline.targets import MAX_TABLE_BYTES, read_table_csv

KEY = "requirements[0].target.file"
SECRET = "S3CRET"

CANTILEVER = """\
name: cantilever
geometry:
  kind: polyline_beam
  points_mm: [[0, 0], [30, 0], [60, 0]]
  thickness_mm: [1.5, 1.5, 1.5]
  width_mm: 8.0
  elements: 30
material: ABS
boundary:
  start: clamped
  end: {control: displacement, direction: [0, 1], max_mm: 20.0, steps: 20}
requirements:
  - name: curve
    quantity: force_N
    x: displacement_mm
    target: {kind: table, file: FILE}
    tolerance_percent: 50
"""

GOOD = "displacement_mm,force_N\n0,0\n10,1\n20,2\n"


def _sparse(size: int):
    def make(path: Path) -> None:
        with open(path, "wb") as handle:
            handle.write(GOOD.encode())
            handle.truncate(size)  # a hole: no disk used

    return make


def _fifo(path: Path) -> None:
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs here")
    os.mkfifo(path)


def _bytes(data: bytes):
    return lambda path: path.write_bytes(data)


#: name -> (make the file at a path, or a fixed path; fragment of the one line)
CASES: dict[str, tuple[object, str]] = {
    "latin1": (_bytes("displacement_mm,force_N\n0,0\n10,1\n20,2 é\n".encode("latin-1")), "UTF-8"),
    "utf16_without_bom": (_bytes(GOOD.encode("utf-16-le")), "UTF-8"),
    "utf16_broken": (_bytes(codecs.BOM_UTF16_LE + GOOD.encode("utf-16-le")[:-1]), "UTF-16"),
    "nul_bytes": (_bytes(GOOD.encode().replace(b"\n10", b"\n\x0010")), "NUL"),
    "field_over_csv_limit": (
        _bytes(("displacement_mm,force_N\n0,0\n10," + "9" * 200_000 + "x\n20,2\n").encode()),
        "not two numbers",
    ),
    "quoted_field_over_limit": (
        _bytes(('displacement_mm,force_N\n0,0\n"' + "1" * 140_000 + "\n20,2\n").encode()),
        "",
    ),
    "300_MB": (_sparse(300 * 1024 * 1024), "larger than 1024 KiB"),
    "1_GB": (_sparse(1024**3), "larger than 1024 KiB"),
    "just_over_the_cap": (_sparse(MAX_TABLE_BYTES + 1), "larger than 1024 KiB"),
    "dev_zero": (Path("/dev/zero"), "not a regular file"),
    "fifo": (_fifo, "not a regular file"),
    "folder": (lambda path: path.mkdir(), "not a regular file"),
    "missing": (lambda path: None, "cannot read"),
    "secret_first_line": (_bytes(f"{SECRET}:x:0:0\nroot\nbin\n".encode()), "two columns"),
    "secret_header": (_bytes(f"{SECRET},{SECRET}2\n0,0\n1,1\n".encode()), "named with a unit"),
    "secret_row": (_bytes(f"displacement_mm,force_N\n0,0\n{SECRET},1\n".encode()), "not two"),
}


@pytest.fixture(scope="module")
def existing_run(tmp_path_factory) -> Path:
    study = validate_study({**flexopt_toys.study(), "optimiser": {"pop_size": 4, "n_gen": 2}})
    out = tmp_path_factory.mktemp("existing") / "run"
    run_study(prepare_run(study), out=out, parallel=ParallelSettings("serial"))
    return out


def snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def _table(case: str, tmp_path: Path) -> Path:
    make, _ = CASES[case]
    if isinstance(make, Path):
        if not make.exists():
            pytest.skip(f"no {make} here")
        return make
    path = tmp_path / "tables" / "table.csv"
    path.parent.mkdir()
    make(path)
    return path


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_hostile_table_file_is_one_quick_line_and_changes_nothing(
    case, existing_run, tmp_path, monkeypatch, capsys, solve_log
):
    table = _table(case, tmp_path)
    study = tmp_path / "study.yaml"
    study.write_text(CANTILEVER.replace("FILE", str(table)), encoding="utf-8")
    workdir = tmp_path / "cwd"
    workdir.mkdir()
    monkeypatch.chdir(workdir)
    before = snapshot(existing_run)
    _, fragment = CASES[case]
    for argv in (
        ["evaluate", str(study)],
        ["evaluate", str(study), "--out", str(existing_run)],
        ["run", str(study), "-q", "--workers", "1", "--quick"],
    ):
        code = main(argv)
        err = capsys.readouterr().err
        assert code == 2, (argv, err[:500])
        lines = err.splitlines()
        assert len(lines) == 1 and "Traceback" not in err, err[:2000]
        assert KEY in lines[0] and fragment in lines[0], lines[0]
        assert SECRET not in err, "an error echoed the file's content"
        assert len(lines[0]) < 1000
        assert solve_log.count == 0, f"{case}: refused after solving: {solve_log.calls}"
    assert list(workdir.iterdir()) == []
    assert snapshot(existing_run) == before


@pytest.mark.parametrize(
    "data",
    [
        GOOD.encode(),
        codecs.BOM_UTF8 + GOOD.encode(),
        codecs.BOM_UTF16_LE + GOOD.encode("utf-16-le"),
        codecs.BOM_UTF16_BE + GOOD.encode("utf-16-be"),
        GOOD.replace("\n", "\r\n").encode(),
    ],
    ids=["utf8", "utf8_bom", "utf16le_bom", "utf16be_bom", "crlf"],
)
def test_the_encodings_documented_are_read(tmp_path, data):
    path = tmp_path / "t.csv"
    path.write_bytes(data)
    (xs, ys), names = read_table_csv(str(path), None)
    assert names == ("displacement_mm", "force_N")
    assert xs.tolist() == [0.0, 10.0, 20.0] and ys.tolist() == [0.0, 1.0, 2.0]


def test_a_table_at_the_cap_is_read(tmp_path):
    path = tmp_path / "t.csv"
    text = GOOD + "# padding\n" * ((MAX_TABLE_BYTES - len(GOOD)) // 10)
    path.write_text(text)
    assert path.stat().st_size <= MAX_TABLE_BYTES
    (xs, _), _ = read_table_csv(str(path), None)
    assert len(xs) == 3


MECHANISM_REQUIREMENT = (
    "  - {name: curve, quantity: force_N, x: drive_mm, target: {kind: table, file: FILE},\n"
    "     tolerance_percent: 50, over: [1, 4]}\n"
)


def _mechanism_study(tmp_path: Path, file: str) -> Path:
    from flexopt.pipeline.study import resolve_study_path

    text = resolve_study_path("parallel-guide").read_text(encoding="utf-8")
    anchor = "  - {quantity: max_abs_shuttle_rotation_deg, max: 0.5}\n"
    assert anchor in text
    path = tmp_path / "guide.yaml"
    path.write_text(text.replace(anchor, anchor + MECHANISM_REQUIREMENT.replace("FILE", file)))
    return path


def test_a_mechanism_study_takes_a_table_file(tmp_path):
    from flexopt.pipeline.studies.mechanism import _requirements

    table = tmp_path / "curve.csv"
    table.write_text("displacement_mm,force_N\n0,0\n2,6\n5,15\n")
    study = load_study(_mechanism_study(tmp_path, str(table)))
    (curve,) = [r for r in _requirements(study) if r.label == "curve"]
    assert float(curve.target(np.array([2.0, 3.5]))[1]) == pytest.approx(10.5)  # from the file, N


def test_a_mechanism_study_refuses_a_bad_table_in_one_line(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    path = _mechanism_study(tmp_path, "/dev/zero" if Path("/dev/zero").exists() else "none.csv")
    assert main(["evaluate", str(path)]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "requirements[6].target.file" in err, err
    assert [p.name for p in tmp_path.iterdir()] == ["guide.yaml"]
