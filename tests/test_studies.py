"""The studies' provenance rule (studies/README.md), checked without running a study.

* Every study script that writes a JSON (``json.dump``, or ``write_text`` / ``write`` of a ``json.dumps``) also
  calls `course_lib.results.provenance`, so what it writes records the command, the commit and the checkpoints'
  sha256.
* Every result JSON in studies/ is described by an entry of its folder's README, and the entry's "Provenance:"
  says "full" exactly when the JSON has the three keys at its top level; any other provenance text (or none, where
  the README's own default says the JSONs record their command only) lists the JSON as lacking provenance.  So a
  rerun that gives a JSON full provenance must update its README entry, and a README cannot claim it otherwise.
* The count line of studies/README.md ("N studies, M result files; K record(s) command + commit + checkpoint
  sha256") is the truth.
"""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import pytest

STUDIES = Path(__file__).resolve().parents[1] / "studies"
KEYS = ("command", "commit", "checkpoints_sha256")
SCRIPTS = sorted(STUDIES.glob("*/*.py"))
RESULTS = sorted(STUDIES.glob("*/*.json"))
FOLDERS = sorted(p for p in STUDIES.iterdir() if p.is_dir() and (p / "README.md").is_file())


def _name(node) -> str:
    """A call's function as dotted text: json.dump, out.write_text, provenance, ..."""
    f = node.func
    parts = []
    while isinstance(f, ast.Attribute):
        parts.append(f.attr)
        f = f.value
    if isinstance(f, ast.Name):
        parts.append(f.id)
    return ".".join(reversed(parts))


def json_writes(tree) -> list[int]:
    """Lines of the calls that write JSON to a file: json.dump(...), and X.write_text / X.write of an argument
    that calls json.dumps (a json.dumps that is only printed does not count)."""
    lines = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        name = _name(node)
        if name == "json.dump":
            lines.append(node.lineno)
        elif name.endswith((".write_text", ".write")) and any(
                isinstance(n, ast.Call) and _name(n) == "json.dumps" for a in node.args for n in ast.walk(a)):
            lines.append(node.lineno)
    return sorted(lines)


def test_the_scan_sees_writes_and_skips_prints():
    tree = ast.parse("import json\nprint(json.dumps(x))\nwith open(p, 'w') as f:\n    json.dump(x, f)\n"
                     "path.write_text(json.dumps(x, indent=1) + '\\n')\nf.write(json.dumps(x))\n")
    assert json_writes(tree) == [4, 5, 6]
    assert json_writes(ast.parse("import json\nprint(json.dumps(x))\n")) == []


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_a_study_that_writes_json_records_its_provenance(script):
    tree = ast.parse(script.read_text())
    writes = json_writes(tree)
    if not writes:  # write_study_result merges the provenance itself
        return
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and _name(n) == "provenance"]
    imported = any(isinstance(n, ast.ImportFrom) and n.module == "course_lib.results"
                   and any(a.name == "provenance" for a in n.names) for n in ast.walk(tree))
    assert calls and imported, (
        f"{script.relative_to(STUDIES.parent)} writes JSON (line {writes[0]}) but does not call "
        "course_lib.results.provenance(): merge its three keys into what it writes, `{**out, **provenance()}`")


def writes_study_result(tree) -> bool:
    return any(isinstance(n, ast.Call) and _name(n) == "write_study_result" for n in ast.walk(tree))


def test_there_are_studies_that_write_json():
    trees = [ast.parse(p.read_text()) for p in SCRIPTS]
    assert sum(bool(json_writes(t)) or writes_study_result(t) for t in trees) >= 10


# ----------------------------------------------------------------------------- the READMEs


def entries(readme: Path) -> dict[str, dict]:
    """A folder README's entries ("- **name** (...)" bullets) -> {name: {"files": [json names], "provenance":
    the text after "Provenance:" up to the end of its sentence, or None}}.  The files: the .json names in the
    parenthesis after the name; a name that is itself a .json; none where the parenthesis says "no result file";
    else ``<name>_results.json`` (the convention of the README that has no file list)."""
    lines = readme.read_text().splitlines()
    out = {}
    for i, line in enumerate(lines):
        if not line.startswith("- **"):
            continue
        block = [line]
        for more in lines[i + 1:]:  # the entry's indented continuation lines
            if not more.startswith((" ", "\t")):
                break
            block.append(more)
        flat = " ".join(" ".join(block).split())
        m = re.match(r"- \*\*([^*]+)\*\*\s*(\((?:[^()]|\([^()]*\))*\))?", flat)
        name, head = m.group(1), m.group(2) or ""
        files = re.findall(r"`([^`]+\.json)`", head)
        if not files:
            files = [] if "no result file" in head else [name] if name.endswith(".json") else [f"{name}_results.json"]
        p = re.search(r"Provenance:\s*(.*?)(?:\.\s|\.$|$)", flat)
        out[name] = {"files": files, "provenance": p.group(1) if p else None}
    return out


def default_provenance(readme: Path) -> str | None:
    """The README's own default ("Provenance: each JSON records its command only ..., unless the entry says
    otherwise"), if it has one."""
    text = " ".join(readme.read_text().split())
    m = re.search(r"Provenance: (each JSON records [^.]*?), unless the entry says", text)
    return m.group(1) if m else None


def claims_full(provenance: str, file: str) -> bool:
    """Whether an entry's provenance text says the JSON ``file`` has full provenance: its text (or the part of it,
    split at ";", that names the file in backticks) starts with "full"."""
    parts = [p.strip() for p in provenance.split(";")]
    named = [p for p in parts if f"`{file}`" in p]
    return any(p.lower().startswith("full") for p in (named or parts[:1]))


def full(path: Path) -> bool:
    data = json.loads(path.read_text())
    return isinstance(data, dict) and all(k in data for k in KEYS) and bool(data["commit"])


@pytest.mark.parametrize("folder", FOLDERS, ids=lambda p: p.name)
def test_each_result_json_is_full_or_listed_as_lacking(folder):
    readme = folder / "README.md"
    table = entries(readme)
    default = default_provenance(readme)
    described = {}
    for name, e in table.items():
        for f in e["files"]:
            assert f not in described, f"{readme}: {f} is described by both {described[f]} and {name}"
            described[f] = name
    problems = []
    for path in sorted(folder.glob("*.json")):
        if path.name not in described:
            problems.append(f"{path.name}: no entry of {readme.name} names it")
            continue
        e = table[described[path.name]]
        text = e["provenance"] or default
        if text is None:
            problems.append(f"{path.name}: entry {described[path.name]} says nothing of its provenance")
            continue
        said, has = claims_full(text, path.name), full(path)
        if said != has:
            problems.append(f"{path.name}: the JSON {'has' if has else 'lacks'} {', '.join(KEYS)} but entry "
                            f"{described[path.name]} says 'Provenance: {text}'"
                            + (" (write 'Provenance: full ...')" if has else ""))
    for name, e in table.items():
        for f in e["files"]:
            if not (folder / f).is_file():
                problems.append(f"entry {name} names {f}, which is not in {folder.name}/")
    assert not problems, "\n".join(problems)


def test_the_readme_parser_on_known_entries(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text(
        "# x\n\n- Provenance: each JSON records its command only (no commit), unless the entry says otherwise.\n\n"
        "## s\n\n- **a** (`a.py` → `a_results.json`,\n  `a2_results.json`). Q? A. Provenance: full\n"
        "  (command, commit, checkpoints' sha256) in `a_results.json`; command only in `a2_results.json`.\n"
        "- **b** (omp). Q? 0.5 m.\n- **c.json** (no script). Provenance: command only.\n"
        "- **d** (no result file). Imported.\n\nA paragraph.\n")
    t = entries(readme)
    assert t["a"]["files"] == ["a_results.json", "a2_results.json"]
    assert claims_full(t["a"]["provenance"], "a_results.json")
    assert not claims_full(t["a"]["provenance"], "a2_results.json")
    assert t["b"] == {"files": ["b_results.json"], "provenance": None}
    assert t["c.json"]["files"] == ["c.json"] and not claims_full(t["c.json"]["provenance"], "c.json")
    assert t["d"]["files"] == []
    assert default_provenance(readme) == "each JSON records its command only (no commit)"


def test_the_count_line_is_the_truth():
    text = " ".join((STUDIES / "README.md").read_text().split())
    m = re.search(r"\*\*(\d+) studies, (\d+) result files; (\d+) records? command \+ commit \+ checkpoint sha256\.\*\*",
                  text)
    assert m, "studies/README.md has no count line '**N studies, M result files; K record command + commit + ...**'"
    truth = (len(SCRIPTS), len(RESULTS), sum(full(p) for p in RESULTS))
    assert tuple(map(int, m.groups())) == truth, f"studies/README.md says {m.groups()}, the folders hold {truth}"


@pytest.mark.parametrize("result", RESULTS, ids=lambda p: p.stem)
def test_each_result_was_recorded_from_a_clean_checkout(result):
    """A result's commit is a full commit id without "+changes": the run's code is exactly that commit's."""
    commit = json.loads(result.read_text()).get("commit", "")
    assert re.fullmatch(r"[0-9a-f]{40}", commit), f"{result.name}: commit {commit!r} is not a clean checkout's"
