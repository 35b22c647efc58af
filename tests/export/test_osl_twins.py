"""Every GLSL function of the fiber model has a visible OSL twin (osl/ mirrors glsl/ file by file).

For each glsl/{common,geometry,fibers}/X.glsl there is osl/{...}/X.osl; each GLSL function ``name`` defined
there has an OSL function ``vf_name`` in the mirrored file, or the OSL file names it in a ``// no-twin:
name (why)`` line; each OSL function there is the twin of a GLSL function of the mirrored file or is listed
in an ``// osl-only: vf_name`` line. Whoever changes a GLSL function sees here which OSL function to change.
Pure text: no Blender needed.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from tests.support.paths import ROOT

GLSL = ROOT / "glsl"
OSL = ROOT / "osl"
MODEL = ("common", "geometry", "fibers")   # the fiber model; stages/ and shading/ differ by design (Cycles closures)

_TYPES = r"(?:void|bool|int|uint|float|vec[234]|ivec[234]|uvec[234]|mat[234]|[A-Z]\w*)"
_GLSL_FN = re.compile(rf"^{_TYPES}\s+(\w+)\s*\([^;{{]*\)\s*\{{", re.M)
_OSL_FN = re.compile(r"^(?:void|int|float|point|vector|normal|color|matrix|string)\s+(vf_\w+)\s*\(", re.M)


def _strip_comments(text: str) -> str:
    return re.sub(r"//[^\n]*", "", text)


def glsl_functions(path: Path) -> set[str]:
    return set(_GLSL_FN.findall(_strip_comments(path.read_text())))


def osl_functions(path: Path) -> set[str]:
    return set(_OSL_FN.findall(_strip_comments(path.read_text())))


def listed(path: Path, tag: str) -> set[str]:
    """Names after ``// tag:`` on any line (up to a parenthesis), e.g. ``// no-twin: loop_canary (why)``."""
    names: set[str] = set()
    for m in re.finditer(rf"//\s*{tag}:\s*([^\n]*)", path.read_text()):
        names.update(re.findall(r"\b\w+\b", m.group(1).split("(")[0]))
    return names


MIRRORED = sorted(p.relative_to(GLSL) for d in MODEL for p in (GLSL / d).glob("*.glsl"))


def test_the_model_is_mirrored():
    assert MIRRORED, "no GLSL fiber model found"
    missing = [str(rel) for rel in MIRRORED if not (OSL / rel.with_suffix(".osl")).is_file()]
    assert not missing, f"GLSL files without an OSL twin under osl/: {missing}"


@pytest.mark.parametrize("rel", MIRRORED, ids=str)
def test_every_glsl_function_has_an_osl_twin(rel):
    glsl, osl = GLSL / rel, OSL / rel.with_suffix(".osl")
    have = osl_functions(osl)
    excused = listed(osl, "no-twin")
    missing = sorted(f for f in glsl_functions(glsl) if f"vf_{f}" not in have and f not in excused)
    assert not missing, (f"{rel}: GLSL functions with no OSL twin in osl/{rel.with_suffix('.osl')}: {missing} "
                         "(port them as vf_NAME, or say why not in a '// no-twin: NAME (why)' line)")


@pytest.mark.parametrize("rel", MIRRORED, ids=str)
def test_every_osl_function_has_a_glsl_twin_or_says_why_not(rel):
    glsl, osl = GLSL / rel, OSL / rel.with_suffix(".osl")
    twins = {f"vf_{f}" for f in glsl_functions(glsl)}
    extra = sorted(f for f in osl_functions(osl) if f not in twins and f not in listed(osl, "osl-only"))
    assert not extra, (f"osl/{rel.with_suffix('.osl')}: functions with no GLSL twin in glsl/{rel}: {extra} "
                       "(list them in an '// osl-only: vf_NAME (why)' line)")


def test_excuses_name_real_functions():
    """A stale ``no-twin`` or ``osl-only`` line (the function was removed or renamed) is an error too."""
    for rel in MIRRORED:
        glsl, osl = GLSL / rel, OSL / rel.with_suffix(".osl")
        assert listed(osl, "no-twin") <= glsl_functions(glsl), f"osl/{rel}: no-twin names no GLSL function"
        assert listed(osl, "osl-only") <= osl_functions(osl), f"osl/{rel}: osl-only names no OSL function"


def test_the_checker_sees_functions():
    """The parser itself: it finds the known functions (a regex that matched nothing would pass all)."""
    assert {"traverse_straight"} <= glsl_functions(GLSL / "fibers/straight.glsl")
    assert {"ray_path", "deepest_ring"} <= glsl_functions(GLSL / "fibers/ray_path.glsl")
    assert {"candidate_run", "candidate"} <= glsl_functions(GLSL / "fibers/candidates.glsl")
    assert {"fiber_entry"} <= glsl_functions(GLSL / "fibers/fiber_entry.glsl")
    assert {"vf_traverse_straight"} <= osl_functions(OSL / "fibers/straight.osl")
    assert {"vf_ray_path"} <= osl_functions(OSL / "fibers/ray_path.osl")
    assert "make_segment" in glsl_functions(GLSL / "geometry/container.glsl")
