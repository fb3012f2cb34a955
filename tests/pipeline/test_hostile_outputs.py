"""Where flexopt writes (issue 23, class 6): only regular files, with the user's umask, and a full
or closed standard output is one line, never a traceback.

No test here ever names the real ``/dev/null`` (or any device) as a target that could be
replaced: a device is reached only through a symbolic link or a FIFO made in ``tmp_path``, and
every case checks the refusal before anything is written.
"""

from __future__ import annotations

import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest
from flexopt.pipeline.cli import main
from flexopt.pipeline.runfolder import regular_target, write_atomic

#: ``flexopt`` as the installed command runs it (``entry``: main, then a quick exit).
CLI = "import sys; from flexopt.pipeline.cli import entry; sys.argv[0] = 'flexopt'; entry()"


def one_line(err: str, fragment: str) -> str:
    lines = err.splitlines()
    assert len(lines) == 1, err[:2000]
    assert "Traceback" not in err
    assert fragment in lines[0], lines[0]
    return lines[0]


def _fifo(tmp_path: Path) -> Path:
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs on this system")
    path = tmp_path / "pipe"
    os.mkfifo(path)
    return path


def _device_link(tmp_path: Path) -> Path:
    """A symbolic link in tmp_path to a character device (the link is what the test names)."""
    device = Path(os.devnull)
    if not device.exists() or not stat.S_ISCHR(os.stat(device).st_mode):
        pytest.skip("no character device to link to")
    link = tmp_path / "device"
    link.symlink_to(device)
    return link


def _targets(tmp_path: Path) -> dict[str, tuple[Path, str]]:
    folder = tmp_path / "folder.json"
    folder.mkdir()
    return {
        "fifo": (_fifo(tmp_path), "is a FIFO"),
        "device": (_device_link(tmp_path), "is a device node"),
        "folder": (folder, "is a folder"),
    }


def _state(path: Path) -> tuple[int, int, int]:
    info = os.lstat(path)
    return info.st_mode, info.st_ino, info.st_size


@pytest.mark.parametrize("what", ["fifo", "device", "folder"])
@pytest.mark.parametrize(
    "argv",
    [
        ["schema", "--out"],
        # the --out check comes before the run folder is read: no run is needed to test it
        ["export", "no-such-run", "--out"],
        ["export", "no-such-run", "--format", "yaml", "--out"],  # the design as a study
    ],
    ids=["schema", "export", "export-yaml"],
)
def test_out_onto_what_is_not_a_regular_file_is_refused_before_any_write(
    tmp_path, capsys, what, argv
):
    target, fragment = _targets(tmp_path)[what]
    before = _state(target)
    inside = sorted(target.iterdir()) if target.is_dir() else None
    link_target = os.readlink(target) if target.is_symlink() else None
    assert main([*argv, str(target)]) == 2
    line = one_line(capsys.readouterr().err, fragment)
    assert "--out" in line and "regular file" in line
    assert _state(target) == before
    if inside is not None:
        assert sorted(target.iterdir()) == inside
    if link_target is not None:
        assert os.readlink(target) == link_target
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_write_atomic_itself_never_replaces_what_is_not_a_regular_file(tmp_path):
    for target, _ in _targets(tmp_path).values():
        before = _state(target)
        with pytest.raises(OSError, match="regular file"):
            write_atomic(target, "x")
        assert _state(target) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["device", "folder.json", "pipe"]


def test_a_link_to_a_regular_file_is_written_through_and_stays_a_link(tmp_path):
    real = tmp_path / "real.json"
    real.write_text("old")
    link = tmp_path / "link.json"
    link.symlink_to(real)
    assert regular_target(link) == real.resolve()
    write_atomic(link, "new")
    assert link.is_symlink() and real.read_text() == "new"


@pytest.mark.parametrize(("umask", "mode"), [(0o077, 0o600), (0o022, 0o644), (0o002, 0o664)])
def test_written_files_honour_the_umask(tmp_path, umask, mode):
    env = {**os.environ}
    out = tmp_path / "schema.json"
    code = (
        f"import os, sys; os.umask({umask:#o}); from flexopt.pipeline.cli import main; "
        f"from flexopt.pipeline.runfolder import write_atomic; from pathlib import Path; "
        f"write_atomic(Path({str(tmp_path / 'direct.txt')!r}), 'x'); "
        f"sys.exit(main(['schema', '--out', {str(out)!r}]))"
    )
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert stat.S_IMODE(out.stat().st_mode) == mode
    assert stat.S_IMODE((tmp_path / "direct.txt").stat().st_mode) == mode


def _cli(argv: list[str], **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", CLI, *argv], capture_output=False, text=True, timeout=60, **kwargs
    )


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
def test_a_full_standard_output_is_one_line_and_exit_1(tmp_path):
    with open("/dev/full", "w") as full:
        done = _cli(["schema"], stdout=full, stderr=subprocess.PIPE)
    assert done.returncode == 1, done.stderr
    one_line(done.stderr, "flexopt schema: error: standard output")


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
@pytest.mark.parametrize("argv", [["--help"], ["--version"], ["run", "--help"]])
def test_help_onto_a_full_standard_output_is_one_line_and_exit_1(argv):
    # argparse prints these before any command runs
    with open("/dev/full", "w") as full:
        done = _cli(argv, stdout=full, stderr=subprocess.PIPE)
    assert done.returncode == 1, done.stderr
    one_line(done.stderr, "flexopt: error: standard output")


@pytest.mark.parametrize("argv", [["list"], ["schema"]])
def test_a_closed_standard_output_is_one_line_and_exit_1(argv):
    # the shell's `flexopt list >&-`: file descriptor 1 closed before Python starts
    done = subprocess.run(
        ["sh", "-c", 'exec "$@" >&-', "sh", sys.executable, "-c", CLI, *argv],
        stderr=subprocess.PIPE,
        text=True,
        timeout=60,
    )
    assert done.returncode == 1, done.stderr
    one_line(done.stderr, f"flexopt {argv[0]}: error: standard output is closed")


def test_init_never_writes_inside_a_folder_named_like_its_file(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.yaml").mkdir()
    assert main(["init", "mine"]) == 2
    one_line(capsys.readouterr().err, "mine.yaml is a folder")
    assert list((tmp_path / "mine.yaml").iterdir()) == []
    # --out naming a folder still means "in that folder", as documented
    (tmp_path / "studies").mkdir()
    assert main(["init", "mine", "--out", "studies"]) == 0
    assert (tmp_path / "studies" / "mine.yaml").is_file()


@pytest.mark.parametrize("what", ["fifo", "device"])
def test_init_out_onto_a_fifo_or_device_is_refused(tmp_path, capsys, what):
    target, _ = _targets(tmp_path)[what]
    before = _state(target)
    assert main(["init", "mine", "--out", str(target)]) == 2
    one_line(capsys.readouterr().err, "exists")
    assert _state(target) == before


def test_a_run_folder_under_umask_077_shares_nothing(tmp_path):
    # every file a run writes (atomic files, the store, the lock, report files) and its folders
    here = Path(__file__).resolve().parent
    out = tmp_path / "run"
    code = (
        "import os, sys, json; os.umask(0o077); sys.path.insert(0, sys.argv[1]); "
        "import flexopt_toys; from flexopt.pipeline.cli import main; "
        "raw = {**flexopt_toys.study(), 'optimiser': {'pop_size': 4, 'n_gen': 1, 'seed': 1}}; "
        "open(sys.argv[2] + '.yaml', 'w').write(json.dumps(raw)); "
        "sys.exit(main(['run', sys.argv[2] + '.yaml', '--out', sys.argv[2], '-q', "
        "'--workers', '1']))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, str(here), str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    paths = [out, *out.rglob("*")]
    assert len(paths) > 5
    for path in paths:
        assert stat.S_IMODE(path.lstat().st_mode) & 0o077 == 0, path
