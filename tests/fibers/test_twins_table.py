"""The twins table of docs/architecture.md is complete and true.

Every GLSL function of the fiber model and the container geometry (glsl/fibers/*, glsl/geometry/*,
glsl/common/hash.glsl) has a row; each named numpy twin imports (module + attribute); each named OSL twin
is defined in the named .osl file; a twin that is ``none`` has a reason. Functions are found by name
across the folders (the file column of the table is a hint that is not checked), so moving a function
between files needs no change here, and adding one fails until its row says where its twins are.
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest
from tests.support.paths import ROOT

DOC = ROOT / "docs" / "architecture.md"

_TYPES = r"(?:void|bool|int|uint|float|vec[234]|ivec[234]|uvec[234]|mat[234]|[A-Z]\w*)"
_GLSL_FN = re.compile(rf"^{_TYPES}\s+(\w+)\s*\([^;{{]*\)\s*\{{", re.M)       # definitions, not prototypes
_OSL_FN = re.compile(r"^(?:void|int|float|point|vector|normal|color|matrix|string|[A-Z]\w*)\s+(vf_\w+)\s*\(",
                     re.M)
_CODE = re.compile(r"`([^`]+)`")
_OSL_TWIN = re.compile(r"^(osl/[\w/]+\.osl):\s*(vf_\w+)$")


def _strip_comments(text: str) -> str:
    return re.sub(r"/\*.*?\*/", "", re.sub(r"//[^\n]*", "", text), flags=re.S)


def glsl_files() -> list[Path]:
    glsl = ROOT / "glsl"
    return sorted((glsl / "fibers").glob("*.glsl")) + sorted((glsl / "geometry").glob("*.glsl")) + [
        glsl / "common" / "hash.glsl"]


def glsl_functions() -> dict[str, str]:
    """{function: file} over the model's GLSL files."""
    found: dict[str, str] = {}
    for path in glsl_files():
        for name in _GLSL_FN.findall(_strip_comments(path.read_text())):
            found.setdefault(name, str(path.relative_to(ROOT)))
    return found


def osl_functions(path: Path) -> set[str]:
    return set(_OSL_FN.findall(_strip_comments(path.read_text())))


def parse_table(text: str) -> dict[str, dict[str, str]]:
    """The rows of the table under '## Twins': {glsl: {numpy, osl, note}}; a name listed twice is an error."""
    section = re.split(r"^## Twins\s*$", text, flags=re.M)
    assert len(section) == 2, f"{DOC.name}: no '## Twins' section"
    body = re.split(r"^## ", section[1], flags=re.M)[0]
    rows: dict[str, dict[str, str]] = {}
    header_seen = False
    for line in body.splitlines():
        if not line.startswith("|"):
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if not header_seen:
            assert [c.lower() for c in cells[:5]] == ["glsl function", "file (hint)", "numpy twin", "osl twin",
                                                      "note"], f"{DOC.name}: unexpected twins table header {cells}"
            header_seen = True
            continue
        if set("".join(cells)) <= set("-: "):
            continue
        assert len(cells) == 5, f"{DOC.name}: a twins row needs 5 cells: {line!r}"
        glsl = _CODE.fullmatch(cells[0])
        assert glsl, f"{DOC.name}: the GLSL function is not in backticks: {line!r}"
        name = glsl.group(1)
        assert name not in rows, f"{DOC.name}: {name} has two rows"
        rows[name] = {"numpy": cells[2], "osl": cells[3], "note": cells[4]}
    assert header_seen, f"{DOC.name}: the Twins section has no table"
    return rows


def _twin(cell: str) -> str | None:
    """The twin named in a cell (backticks stripped), or None for 'none'."""
    if cell.lower() == "none":
        return None
    m = _CODE.fullmatch(cell)
    assert m, f"a twin is `name` or none, not {cell!r}"
    return m.group(1)


@pytest.fixture(scope="module")
def table() -> dict[str, dict[str, str]]:
    return parse_table(DOC.read_text(encoding="utf-8"))


def test_the_model_has_functions_to_check():
    found = glsl_functions()
    assert {"lowbias32", "fiber_center", "to_unit_space", "traverse_straight"} <= set(found), sorted(found)


def test_every_glsl_function_has_a_row(table):
    missing = {n: f for n, f in glsl_functions().items() if n not in table}
    assert not missing, (f"GLSL functions missing from the twins table of docs/architecture.md: {missing} "
                         "(add a row: its numpy twin in app.fibers or app.reference, its OSL twin, or why none)")


def test_no_row_names_a_removed_function(table):
    stale = sorted(set(table) - set(glsl_functions()))
    assert not stale, f"docs/architecture.md twins rows for GLSL functions that no longer exist: {stale}"


def test_numpy_twins_exist(table):
    bad = []
    for name, row in table.items():
        twin = _twin(row["numpy"])
        if twin is None:
            continue
        module, _, attr = twin.rpartition(".")
        if module not in ("app.fibers", "app.reference"):
            bad.append(f"{name}: numpy twin {twin} is neither in app.fibers nor in app.reference")
            continue
        if not hasattr(importlib.import_module(module), attr):
            bad.append(f"{name}: {module} has no {attr}")
    assert not bad, "\n".join(bad)


def test_osl_twins_exist(table):
    bad = []
    for name, row in table.items():
        twin = _twin(row["osl"])
        if twin is None:
            continue
        m = _OSL_TWIN.match(twin)
        if not m:
            bad.append(f"{name}: OSL twin {twin!r} is not 'osl/FILE.osl: vf_NAME'")
            continue
        path = ROOT / m.group(1)
        if not path.is_file():
            bad.append(f"{name}: {m.group(1)} does not exist")
        elif m.group(2) not in osl_functions(path):
            bad.append(f"{name}: {m.group(2)} is not defined in {m.group(1)}")
    assert not bad, "\n".join(bad)


def test_a_missing_twin_says_why(table):
    silent = sorted(n for n, row in table.items()
                    if (_twin(row["numpy"]) is None or _twin(row["osl"]) is None) and not row["note"])
    assert not silent, f"twins rows with a twin 'none' and no reason in the note: {silent}"


def test_the_checks_can_fail():
    """The parser sees a removed row, a misnamed numpy twin and a misnamed OSL twin (so the tests above are
    not vacuous)."""
    text = DOC.read_text(encoding="utf-8")
    rows = parse_table(text)
    without = "\n".join(line for line in text.splitlines() if not line.startswith("| `lowbias32` |"))
    assert "lowbias32" in rows and "lowbias32" not in parse_table(without)
    broken = text.replace("`app.fibers.fiber_key`", "`app.fibers.fiber_kee`").replace(
        "`osl/common/hash.osl: vf_ring_key`", "`osl/common/hash.osl: vf_ring_kee`")
    rows = parse_table(broken)
    assert not hasattr(importlib.import_module("app.fibers"), _twin(rows["fiber_key"]["numpy"]).rpartition(".")[2])
    path, fn = _OSL_TWIN.match(_twin(rows["ring_key"]["osl"])).groups()
    assert fn not in osl_functions(ROOT / path)
