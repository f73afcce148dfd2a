"""The docs as a user meets them: a short README whose links all lead
somewhere, every doc file reached from it, and no development log in the
repository's files (history belongs in commit messages)."""
import re

from conftest import ROOT

FOLDERS = ["docs", "src", "post", "tests", "bench", "examples", "input", "cmake"]
# words of a development log: numbered steps of the work, sessions, the
# machines figures were borrowed from
# (Fortran's `error stop 1` and `stop 2` statements and pytest's
# scope="session" are not)
FORTRAN_STOP = re.compile(r"\s*(error )?stop \d+\s*")
LOG_WORDS = re.compile(r"(?<!error )\b(stop|stops) \d+\b|(?<!scope=\")\bsession\b|\bborrowed\b|\blent machine\b",
                       re.I)


def links(markdown):
    return [target for target in re.findall(r"\]\(([^)#\s]+)", markdown) if "://" not in target]


def test_readme_is_short_and_its_links_resolve():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 250
    targets = links(readme)
    assert {"docs/usage.md", "docs/inputs.md", "docs/output.md", "docs/performance.md", "docs/design.md",
            "LICENSE", "CITATION.cff"} <= set(targets)
    for target in targets:
        assert (ROOT / target).exists(), target
    reached = {pathlib_name for pathlib_name in (t.split("/")[-1] for t in targets)}
    for doc in (ROOT / "docs").glob("*.md"):
        assert doc.name in reached, f"docs/{doc.name} is not linked from the README"
        for target in links(doc.read_text()):
            assert (doc.parent / target).exists(), f"docs/{doc.name}: {target}"


def repository_text_files():
    paths = [ROOT / "README.md", ROOT / "CMakeLists.txt", ROOT / "CITATION.cff"]
    for folder in FOLDERS:
        paths += [p for p in (ROOT / folder).rglob("*") if p.is_file() and p.suffix in
                  {".md", ".f90", ".c", ".py", ".sh", ".nml", ".cmake", ".txt", ".in", ".bash", ".toml", ".sbatch"}
                  and "egg-info" not in str(p)]
    return paths


def test_no_file_outside_the_repository_is_cited():
    """The model's derivation is docs/model.md; nothing refers to notes that are not in the repository."""
    outside = re.compile(r"physics\.md|\.\./shared\b")
    found = [f"{path.relative_to(ROOT)}:{number}: {line.strip()}" for path in repository_text_files()
             if path.name != "test_docs.py"
             for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1) if outside.search(line)]
    assert found == []


def test_no_development_log_in_the_files():
    found = []
    for path in repository_text_files():
        if path.name == "test_docs.py":
            continue
        for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            if LOG_WORDS.search(line) and not FORTRAN_STOP.fullmatch(line):
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert found == []
