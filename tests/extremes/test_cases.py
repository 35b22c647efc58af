"""The twelve cases of ``vfiber bench extremes`` at the quick level: each must pass. The bench's full level
(``python -m app.bench.extremes``) adds the slow configurations; ``-m slow`` runs some of them here."""

from __future__ import annotations

import pytest

from app.bench.extremes import CASES, Lab, case_many_fibers


@pytest.fixture(scope="module")
def lab(ctx):
    return Lab(ctx, quick=True)


@pytest.mark.parametrize("number", sorted(CASES))
def test_case(ctx, lab, number):
    assert ctx.error == "GL_NO_ERROR"
    case = CASES[number](lab)
    assert case.passed, f"case {number} ({case.title}): {case.measure} = {case.rate:.3g}; {case.notes}"
    assert ctx.error == "GL_NO_ERROR"


@pytest.mark.slow
def test_many_fibers_full(ctx):
    """64 rings at 0.01 degrees with thin fibers, one ring of 36,000 ellipsoid fibers, and 64 rings at 0.01
    degrees curled and twisted (2.3 million curved fibers: ~2,600 draws per pass): exact == brute."""
    case = case_many_fibers(Lab(ctx, quick=False))
    assert case.passed, case.notes
