"""The docs a reader needs live in the repo: every path README.md and docs/*.md point to exists,
and none points outside the repo (a clone has no ../shared)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
#: A backticked or linked path into the repo: starts with one of its top-level folders.
TOP = ("configs", "docs", "impulse_core", "optimizer", "studies", "tests")
PATH = re.compile(r"(?:`|\]\()((?:" + "|".join(TOP) + r")/[\w./-]*)(?:`|\))")


def _paths(doc: Path) -> list[str]:
    return [m.rstrip("/.") for m in PATH.findall(doc.read_text())]


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_every_path_a_doc_names_exists(doc: Path) -> None:
    paths = _paths(doc)
    missing = [p for p in paths if not (ROOT / p).exists()]
    assert not missing, f"{doc.name} names paths that do not exist: {missing}"


def test_docs_name_paths_and_never_point_outside_the_repo() -> None:
    assert {"docs/MODEL_FORMAT.md", "docs/ERRATA.md", "docs/ARCHITECTURE.md"} <= set(_paths(ROOT / "README.md"))
    for doc in DOCS:
        assert "../shared" not in doc.read_text(), doc.name


def test_the_readme_python_snippet_runs(tmp_path, monkeypatch) -> None:
    """The README's Python example runs as written (from the repo root) and its batch agrees
    with the one-design evaluation it stands for."""
    text = (ROOT / "README.md").read_text()
    snippet = text.split("```python\n", 1)[1].split("```", 1)[0]
    monkeypatch.chdir(ROOT)
    names: dict = {}
    exec(compile(snippet.replace("~/.cache/footopt", str(tmp_path)), "README.md", "exec"), names)  # noqa: S102 (our own README)
    from impulse_core.evaluate import evaluate
    from optimizer.config.model_file import load_model_file

    model = load_model_file(ROOT / "configs" / "paper_case3.yaml")
    single = evaluate(model.tree, model.scene)
    assert names["out"].external_norm.shape == (1000,)
    assert abs(names["out"].external_norm[0] - single.external_norm) < 1e-12 * single.external_norm
