"""docs/api.md runs: every ```python block, in order, in one namespace, in a fresh folder.

The page is what a notebook user reads top to bottom; a block that no longer runs (a renamed
function, a changed result) fails here. The page also names every public name of flexopt.
"""

from __future__ import annotations

import re
from pathlib import Path

import flexopt
import pytest

PAGE = Path(__file__).resolve().parents[2] / "docs" / "api.md"
BLOCK = re.compile(r"^```python\n(.*?)^```", re.DOTALL | re.MULTILINE)


def python_blocks(text: str) -> list[str]:
    """The code of every ```python block of a Markdown page, in order."""
    return [match.group(1) for match in BLOCK.finditer(text)]


def test_python_blocks_are_found() -> None:
    text = "a\n```python\nx = 1\n```\n```sh\nls\n```\n```python\ny = x\n```\n"
    assert python_blocks(text) == ["x = 1\n", "y = x\n"]


def test_the_page_names_every_public_name() -> None:
    text = PAGE.read_text(encoding="utf-8")
    missing = [name for name in flexopt.__all__ if f"{name}" not in text]
    assert not missing, f"docs/api.md does not mention {missing}"


def test_every_python_block_runs_in_order(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    monkeypatch.chdir(tmp_path)
    blocks = python_blocks(PAGE.read_text(encoding="utf-8"))
    assert len(blocks) >= 10
    namespace: dict[str, object] = {"__name__": "__docs__"}
    for number, code in enumerate(blocks, 1):
        try:
            exec(compile(code, f"docs/api.md block {number}", "exec"), namespace)
        except Exception as exc:
            raise AssertionError(f"docs/api.md block {number} failed:\n{code}") from exc
    printed = capsys.readouterr().out
    # what the page promises the reader sees
    assert "cantilever polyline_beam" in printed
    assert "overall: MET" in printed
    assert "geometry.widht_mm -> " in printed and "did you mean geometry.width_mm?" in printed
    assert (tmp_path / "cantilever.png").stat().st_size > 10_000
    assert (tmp_path / "runs" / "constant-force-quick" / "best.json").is_file()
