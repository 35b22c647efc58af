"""One headless GL context for the whole session, a renderer on it, the Blender harness for the Cycles
tests, and the golden-image options."""

from __future__ import annotations

import pytest

from app.gl.context import create_headless
from app.render.explicit import ExplicitRenderer
from app.render.renderer import Renderer


def pytest_addoption(parser):
    parser.addoption("--regen-goldens", action="store_true", help="rewrite tests/goldens/*.png")


@pytest.fixture(scope="session")
def gl():
    hc = create_headless()
    yield hc
    hc.release()


@pytest.fixture(scope="session")
def ctx(gl):
    return gl.ctx


@pytest.fixture()
def renderer(ctx):
    assert ctx.error == "GL_NO_ERROR"
    r = Renderer(ctx)
    yield r
    r.release_targets()
    assert ctx.error == "GL_NO_ERROR", "the test left a GL error behind"


@pytest.fixture()
def explicit(ctx):
    """The explicit baseline (every fiber a ribbon), released after the test."""
    assert ctx.error == "GL_NO_ERROR"
    e = ExplicitRenderer(ctx)
    yield e
    e.release()
    e.release_targets()
    assert ctx.error == "GL_NO_ERROR", "the test left a GL error behind"


@pytest.fixture()
def regen_goldens(request) -> bool:
    return request.config.getoption("--regen-goldens")


@pytest.fixture(scope="session")
def cycles():
    """app.export.blender (bpy in a child process), or the test is skipped with the reason."""
    from app.export import blender as B

    ok, why = B.blender_available()
    if not ok:
        pytest.skip(f"Blender harness unavailable: {why}")
    return B
