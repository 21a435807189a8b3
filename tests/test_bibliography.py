"""Every system names its source document by a title of the bibliography, and the generated
docs pages (systems table, bibliography) are what the systems say today."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from mechsim.systems import system_class, system_ids
from mechsim.systems.bibliography import DOCUMENTS, documents_cited

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("sid", system_ids())
def test_source_names_a_document(sid: str) -> None:
    source = system_class(sid).source
    assert documents_cited(source), f"{sid}: {source!r} names none of the four documents"
    assert "seed 0" not in source and "catalog" not in source


def test_every_document_is_cited_and_titled() -> None:
    cited = {d.key for sid in system_ids() for d in documents_cited(system_class(sid).source)}
    assert cited == {d.key for d in DOCUMENTS}
    for d in DOCUMENTS:
        assert d.title and d.kind and d.author and d.sections


def test_code_and_tests_cite_documents_by_title() -> None:
    """No docstring or comment cites a document by a key of the project's own catalog
    (the word seed and a catalog number) that a reader of the document cannot look up."""
    key = re.compile(r"seeds? 00[0-3]\b")
    found = [f"{p.relative_to(ROOT)}:{n}" for top in ("src", "tests", "tools")
             for p in sorted((ROOT / top).rglob("*.py"))
             for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
             if key.search(line)]
    assert not found, found


def test_docs_pages_are_up_to_date() -> None:
    r = subprocess.run([sys.executable, str(ROOT / "tools" / "readme_systems.py"), "--check"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
