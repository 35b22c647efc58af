"""GL plumbing: headless contexts (EGL, OSMesa), error messages for people, #include expansion, the
compile-error line table, the program cache and the doctor."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import moderngl
import numpy as np
import pytest

from app.doctor import doctor_report
from app.gl import context as glctx
from app.gl.context import GLContextError, HeadlessContext, create_headless, create_window
from app.gl.shaders import (
    DEFINES_FILE,
    ProgramCache,
    ShaderCompileError,
    ShaderIncludeError,
    expand,
    glsl_root,
    glslang_path,
    validate_with_glslang,
)
from tests.support.paths import ROOT, GLSL_FIXTURES

FIXTURES = GLSL_FIXTURES
REPO = ROOT


def _osmesa_installed() -> bool:
    try:
        glctx._open_library(glctx._OSMESA_LIBS)
    except OSError:
        return False
    return True


needs_osmesa = pytest.mark.skipif(not _osmesa_installed(),
                                  reason="libOSMesa not installed (apt-get install libosmesa6)")


@pytest.fixture
def ctx(gl: HeadlessContext) -> Iterator[moderngl.Context]:
    """conftest's session context, made current: the tests here make and release their own as well."""
    gl.make_current()
    assert gl.ctx.error == "GL_NO_ERROR", "a GL error was left over before the test"
    yield gl.ctx
    assert gl.ctx.error == "GL_NO_ERROR", "the test left a GL error behind"


def _clear_and_read(ctx: moderngl.Context, rgba: tuple[float, float, float, float]) -> np.ndarray:
    fbo = ctx.simple_framebuffer((4, 4))
    fbo.use()
    fbo.clear(*rgba)
    pixels = np.frombuffer(fbo.read(components=4), dtype=np.uint8).reshape(4, 4, 4)
    assert ctx.error == "GL_NO_ERROR"
    return pixels


def _draw(ctx: moderngl.Context, program: moderngl.Program) -> tuple[int, ...]:
    """One full-screen triangle over blue; the first pixel. Sets the state it needs: other tests leave
    culling, depth and blending on in the shared context."""
    ctx.enable_only(moderngl.NOTHING)
    fbo = ctx.simple_framebuffer((4, 4))
    fbo.use()
    fbo.clear(0.0, 0.0, 1.0, 1.0)
    ctx.vertex_array(program, []).render(moderngl.TRIANGLES, vertices=3)
    return tuple(fbo.read(components=4)[:4])


def _line_of(path: Path, marker: str) -> int:
    return next(n for n, line in enumerate(path.read_text().splitlines(), start=1) if marker in line)


# ------------------------------------------------------------------------------------------ contexts

def test_egl_context_is_llvmpipe_45_core() -> None:
    with create_headless("egl") as hc:
        assert hc.backend == "egl" and hc.attempts == []
        assert "llvmpipe" in hc.renderer, f"goldens assume llvmpipe, got {hc.renderer}"
        assert hc.ctx.version_code >= 450 and "Core Profile" in hc.version
        assert hc.ctx.error == "GL_NO_ERROR"
        pixels = _clear_and_read(hc.ctx, (1.0, 0.5, 0.0, 1.0))
        assert (pixels == [255, 128, 0, 255]).all()


@needs_osmesa
def test_osmesa_fallback_when_forced(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(glctx.ENV_BACKEND, "osmesa")
    with create_headless() as hc:  # "auto" obeys the environment variable
        assert hc.backend == "osmesa"
        assert "llvmpipe" in hc.renderer and hc.ctx.version_code >= 450
        assert "Core Profile" in hc.version
        pixels = _clear_and_read(hc.ctx, (0.0, 1.0, 0.0, 1.0))
        assert (pixels == [0, 255, 0, 255]).all()
        # Programs compile and draw through OSMesa's function pointers, not only clears.
        program = ProgramCache(FIXTURES).get(hc.ctx, "quad.vert", "color.frag", {"RED": 1})
        assert _draw(hc.ctx, program) == (255, 128, 0, 255)
        assert hc.ctx.error == "GL_NO_ERROR"


@needs_osmesa
def test_auto_falls_back_to_osmesa_when_egl_breaks(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(glctx.ENV_BACKEND, raising=False)

    def no_egl(require: int) -> None:
        raise GLContextError("EGL could not load libEGL.so.1: install libegl1 libegl-mesa0")

    monkeypatch.setitem(glctx._CREATORS, "egl", no_egl)
    with create_headless() as hc:
        assert hc.backend == "osmesa"
        assert hc.attempts == [("egl", "EGL could not load libEGL.so.1: install libegl1 libegl-mesa0")]


@needs_osmesa
def test_releasing_a_second_context_gives_the_first_back() -> None:
    # Mesa's EGL and OSMesa share one GL dispatch: the newest context takes it, release must return it.
    with create_headless("egl") as first:
        fbo = first.ctx.simple_framebuffer((2, 2))
        fbo.use()
        fbo.clear(0.0, 0.0, 1.0, 1.0)
        for backend in ("osmesa", "egl"):
            second = create_headless(backend)
            other = second.ctx.simple_framebuffer((2, 2))
            other.use()
            other.clear(1.0, 0.0, 0.0, 1.0)
            first.make_current()
            assert tuple(fbo.read(components=4)[:4]) == (0, 0, 255, 255), f"make_current after {backend}"
            second.make_current()
            assert tuple(other.read(components=4)[:4]) == (255, 0, 0, 255)
            second.release()
            assert tuple(fbo.read(components=4)[:4]) == (0, 0, 255, 255), f"release of {backend}"
            assert first.ctx.error == "GL_NO_ERROR"


@pytest.mark.parametrize("backend, package", [("egl", "libegl1"), ("osmesa", "libosmesa6")])
def test_missing_library_names_the_package(monkeypatch: pytest.MonkeyPatch, backend: str, package: str) -> None:
    def broken(names: object) -> None:
        raise OSError("libX.so: cannot open shared object file: No such file or directory")

    monkeypatch.setattr(glctx, "_open_library", broken)
    monkeypatch.setattr(glctx, "_egl_lib", None)
    with pytest.raises(GLContextError) as info:
        create_headless(backend)
    message = str(info.value)
    assert package in message and "apt-get install" in message
    assert "\n" not in message and "Traceback" not in message
    # `from None`: nothing chained that a traceback printer would show
    assert info.value.__cause__ is None and (info.value.__context__ is None or info.value.__suppress_context__)
    assert info.value.attempts == [(backend, message)]


def test_all_backends_broken_lists_each(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(glctx.ENV_BACKEND, raising=False)
    monkeypatch.setattr(glctx, "_open_library", lambda names: (_ for _ in ()).throw(OSError("nope")))
    monkeypatch.setattr(glctx, "_egl_lib", None)
    with pytest.raises(GLContextError) as info:
        create_headless()
    assert [b for b, _ in info.value.attempts] == ["egl", "osmesa"]
    assert "libegl1" in str(info.value) and "libosmesa6" in str(info.value)


@pytest.mark.parametrize("driver_message, package", [
    ("eglInitialize failed (0x3001)", "libgl1-mesa-dri"),
    ("requested device index 0, but found 0 devices", "libegl-mesa0"),
    ("libGL.so.1 not loaded", "libgl1"),
    ("Requested OpenGL version 450, got version 330", "OpenGL 3.3"),
])
def test_driver_failures_become_package_hints(monkeypatch: pytest.MonkeyPatch, driver_message: str,
                                              package: str) -> None:
    def fail(**kwargs: object) -> None:
        raise Exception(driver_message)

    monkeypatch.setattr(moderngl, "create_standalone_context", fail)
    with pytest.raises(GLContextError) as info:
        create_headless("egl")
    assert package in str(info.value) and "\n" not in str(info.value)


def test_unknown_backend_in_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(glctx.ENV_BACKEND, "vulkan")
    with pytest.raises(GLContextError, match="VFIBER_GL_BACKEND"):
        create_headless()


def test_window_without_display_says_so(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(GLContextError, match="^no display: .*xvfb-run"):
        create_window(64, 48, "vfiber test", visible=False)


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="xvfb-run not installed (apt-get install xvfb)")
def test_window_under_xvfb() -> None:
    # A subprocess: a GLX window and this process's EGL contexts must not meet on one thread.
    script = textwrap.dedent("""
        import glfw
        from app.gl.context import create_window
        w = create_window(64, 48, "vfiber test", visible=False)
        w.ctx.clear(1.0, 0.0, 0.0, 1.0)  # the window's own framebuffer
        fbo = w.ctx.simple_framebuffer((2, 2))  # read back through an FBO: moderngl 5.13 reading
        fbo.use()                               # the default framebuffer leaves GL_INVALID_OPERATION
        fbo.clear(1.0, 0.0, 0.0, 1.0)
        print(w.framebuffer_size, w.ctx.version_code, fbo.read(viewport=(0, 0, 1, 1)).hex(), w.ctx.error)
        glfw.terminate()
    """)
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["PYTHONPATH"] = str(REPO)
    result = subprocess.run(["xvfb-run", "-a", sys.executable, "-c", script], capture_output=True, text=True,
                            env=env, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["(64,", "48)", "450", "ff0000", "GL_NO_ERROR"]


# ------------------------------------------------------------------------------------------- includes

def test_nested_includes_expand_each_file_once() -> None:
    text, table = expand("nested.frag", root=FIXTURES)
    lines = text.splitlines()
    assert lines.count("float lib_b(float x) { return 2.0 * x; }") == 1
    assert lines.count("float lib_a(float x) { return lib_b(x) + 1.0; }") == 1
    assert lines[0] == "#version 450"
    assert not any(line.lstrip().startswith("#include") for line in lines)
    assert len(lines) == len(table)
    # Every expanded line is exactly the line the table says it came from.
    for expanded, (rel, number) in zip(lines, table):
        assert (FIXTURES / rel).read_text().splitlines()[number - 1] == expanded
    # b's body comes before a's, since a includes b before defining lib_a.
    assert table.index(("lib/b.glsl", 3)) < table.index(("lib/a.glsl", 4))


def test_defines_go_right_after_version() -> None:
    text, table = expand("nested.frag", {"MODE": 2, "DEBUG": True, "EPS": 1e-4, "FLAG": None}, root=FIXTURES)
    lines = text.splitlines()
    assert lines[:5] == ["#version 450", "#define DEBUG 1", "#define EPS 0.0001", "#define FLAG",
                         "#define MODE 2"]
    assert table[0] == ("nested.frag", 1) and table[1:5] == [(DEFINES_FILE, n) for n in range(1, 5)]
    assert table[5] == ("nested.frag", 2)
    with pytest.raises(ValueError, match="identifier"):
        expand("nested.frag", {"not a name": 1}, root=FIXTURES)


def test_include_cycle_names_the_chain() -> None:
    with pytest.raises(ShaderIncludeError) as info:
        expand("cycle.frag", root=FIXTURES)
    assert str(info.value) == ("include cycle: glsl_fixtures/cycle/x.glsl:2 -> glsl_fixtures/cycle/y.glsl:3"
                               " -> glsl_fixtures/cycle/x.glsl")


def test_missing_include_names_the_including_line() -> None:
    with pytest.raises(ShaderIncludeError) as info:
        expand("missing.frag", root=FIXTURES)
    assert str(info.value).startswith('glsl_fixtures/missing.frag:4: cannot include "lib/nope.glsl"')
    with pytest.raises(ShaderIncludeError, match="glsl_fixtures/absent.frag does not exist"):
        expand("absent.frag", root=FIXTURES)


def test_glsl_root_is_the_library() -> None:
    root = glsl_root()
    assert root.name == "glsl" and root.is_dir()


# ---------------------------------------------------------------------------------- compile errors

def test_compile_error_points_at_the_library_line(ctx: moderngl.Context) -> None:
    expected = _line_of(FIXTURES / "broken.glsl", "BROKEN")
    with pytest.raises(ShaderCompileError) as info:
        ProgramCache(FIXTURES).get(ctx, "quad.vert", "broken.frag", {"A": 1, "B": 2, "C": 3})
    message = str(info.value)
    assert "Traceback" not in message
    located = [d for d in info.value.diagnostics if d.startswith("glsl_fixtures/broken.glsl:")]
    assert located, message
    # Mesa gives LINE(COL); the column must survive, the line must be broken.glsl's, not the expansion's.
    assert located[0].startswith(f"glsl_fixtures/broken.glsl:{expected}:"), message
    assert "undeclaredThing" in located[0]
    assert "0:" not in message.split("\n", 1)[1], "a raw driver location was left in the message"


# ------------------------------------------------------------------------------------------- cache

def test_program_cache_by_defines(ctx: moderngl.Context) -> None:
    cache = ProgramCache(FIXTURES)
    red = cache.get(ctx, "quad.vert", "color.frag", {"RED": 1})
    assert cache.get(ctx, "quad.vert", "color.frag", {"RED": 1}) is red
    black = cache.get(ctx, "quad.vert", "color.frag", {"RED": 0})
    assert black is not red
    # A changed define must change the image.
    assert [_draw(ctx, red), _draw(ctx, black)] == [(255, 128, 0, 255), (0, 128, 0, 255)]


def test_cache_watches_files_for_hot_reload(ctx: moderngl.Context, tmp_path: Path) -> None:
    root = tmp_path / "glsl"
    shutil.copytree(FIXTURES, root)
    cache = ProgramCache(root)
    first = cache.get(ctx, "quad.vert", "color.frag")
    assert not cache.sources_changed()
    library = root / "lib" / "b.glsl"  # an included file, two levels down
    library.write_text(library.read_text().replace("2.0 * x", "4.0 * x"))
    os.utime(library, ns=(library.stat().st_atime_ns, library.stat().st_mtime_ns + 10**9))
    assert cache.sources_changed()
    assert cache.get(ctx, "quad.vert", "color.frag") is first  # until invalidated
    cache.invalidate()
    second = cache.get(ctx, "quad.vert", "color.frag")
    assert second is not first and not cache.sources_changed()


def test_failed_compile_is_watched_too(ctx: moderngl.Context, tmp_path: Path) -> None:
    root = tmp_path / "glsl"
    shutil.copytree(FIXTURES, root)
    cache = ProgramCache(root)
    with pytest.raises(ShaderIncludeError):
        cache.get(ctx, "quad.vert", "missing.frag")
    assert not cache.sources_changed()
    (root / "lib" / "nope.glsl").write_text("// now it exists\n")
    assert cache.sources_changed()


# ----------------------------------------------------------------------------------------- glslang

needs_glslang = pytest.mark.skipif(glslang_path() is None,
                                   reason="glslangValidator missing (apt-get install glslang-tools)")


@needs_glslang
def test_glslang_maps_lines_through_includes() -> None:
    validate_with_glslang("nested.frag", root=FIXTURES)
    with pytest.raises(ShaderCompileError) as info:
        validate_with_glslang("broken.frag", {"X": 1}, root=FIXTURES)
    expected = _line_of(FIXTURES / "broken.glsl", "BROKEN")
    assert info.value.diagnostics[0].startswith(f"glsl_fixtures/broken.glsl:{expected}: error:"), str(info.value)


def _stage_files() -> list[str]:
    root = glsl_root()
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*") if p.suffix in (".vert", ".frag"))


@needs_glslang
@pytest.mark.parametrize("stage", _stage_files())
def test_every_stage_file_passes_glslang(stage: str) -> None:
    validate_with_glslang(stage)


# ------------------------------------------------------------------------------------------- doctor

def test_doctor_reports_the_renderer() -> None:
    lines = doctor_report()
    text = "\n".join(lines)
    assert "llvmpipe" in text and "moderngl" in text
    egl = next(line for line in lines if line.strip().startswith("egl "))
    assert "ok:" in egl
    assert any(line.strip().startswith("chosen ") for line in lines)
    assert any(line.strip().startswith("glslang ") for line in lines)


def test_doctor_never_raises(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(glctx, "_open_library", lambda names: (_ for _ in ()).throw(OSError("nope")))
    monkeypatch.setattr(glctx, "_egl_lib", None)
    monkeypatch.setattr(glctx, "create_headless", lambda backend="auto": 1 / 0)
    monkeypatch.setattr(glctx, "probe_backend", lambda name, *a, **k: 1 / 0)  # the doctor probes in children
    lines = doctor_report()
    assert any("probe failed" in line for line in lines)
    assert any(line.strip().startswith("python ") for line in lines)


def test_clear_targets_zeroes_every_attachment_type(ctx: moderngl.Context) -> None:
    """renderer.clear_targets relies on moderngl clearing each attachment with the glClearBuffer call of
    its type: integer ids must read 0 (plain glClear leaves integer attachments undefined), floats and
    unorm colour 0, depth 1. Written full of non-zero values first, so a clear that skips one fails."""
    from app.render.renderer import clear_targets

    size = (8, 4)
    color = ctx.texture(size, 4, np.full((4, 8, 4), 200, np.uint8).tobytes(), dtype="f1")
    ids = ctx.texture(size, 4, np.full((4, 8, 4), 0xDEADBEEF, np.uint32).tobytes(), dtype="u4")
    geom = ctx.texture(size, 4, np.full((4, 8, 4), -3.5, np.float32).tobytes(), dtype="f4")
    depth = ctx.depth_texture(size, np.full((4, 8), 0.25, np.float32).tobytes())
    fbo = ctx.framebuffer([color, ids, geom], depth)
    try:
        clear_targets(fbo)
        assert not np.frombuffer(color.read(), np.uint8).any()
        assert not np.frombuffer(ids.read(), np.uint32).any()
        assert not np.frombuffer(geom.read(), np.float32).any()
        assert np.all(np.frombuffer(depth.read(), np.float32) == 1.0)
    finally:
        fbo.release()
        for t in (color, ids, geom, depth):
            t.release()
