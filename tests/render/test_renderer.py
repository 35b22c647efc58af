"""The renderer's contract: constant scene memory, parameters that matter, finite outputs, clear errors,
and golden images that catch regressions (on llvmpipe only)."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from app.gl.shaders import ProgramCache, ShaderCompileError, glsl_root
from app.render.renderer import Renderer, scene_gpu_bytes
from tests.support.ids import setup
from tests.support.goldens import check_golden, require_llvmpipe
from tests.support.paths import GOLDENS

SIZE = (160, 96)


@pytest.mark.parametrize("a,b", [({"fibers.phi_step": 1.0}, {"fibers.phi_step": 180.0}),
                                 ({"fibers.rings": 1, "fibers.fiber_radius": 0.01},
                                  {"fibers.rings": 40, "fibers.fiber_radius": 0.01})])
def test_scene_gpu_bytes_do_not_depend_on_fiber_count(renderer, a, b):
    sizes = []
    for values in (a, b):
        p, scene, cam = setup(renderer, values)
        sizes.append((renderer.scene_gpu_bytes, scene_gpu_bytes(scene)))
        frame = renderer.render(p, cam, SIZE, outputs=("ids",))
        assert frame.hit.any()
    assert sizes[0] == sizes[1]
    assert sizes[0][0] == sizes[0][1]


CHANGES = [("fibers.rings", 6), ("fibers.phi_step", 6.0), ("fibers.phi_increment", 2.0),
           ("fibers.even_spacing", 1.0), ("fibers.fiber_radius", 0.02), ("fibers.radial_jitter", 1.0),
           ("fibers.angular_jitter", 0.0), ("fibers.length_jitter", 0.8), ("fibers.hash", "thesis"),
           ("fibers.seed", 7), ("scene.taper", 0.5), ("scene.bend", 40.0), ("look.color", (0.1, 0.2, 0.9)),
           ("look.roughness", 0.9), ("look.light_azimuth", -120.0), ("look.self_shadow", "off"),
           ("camera.azimuth", 80.0), ("look.model", "marschner"), ("look.color_mode", "melanin"),
           ("look.exposure", 1.0), ("look.self_shadow", "traced"), ("look.shadow_density", 0.1),
           ("look.ambient", 2.0), ("look.tint_variation", 1.0), ("quality.supersample", 2),
           ("quality.msaa", 4), ("shape.twist", 0.5), ("shape.curl_amplitude", 0.3),
           ("shape.ellipsoid", 0.8)]


@pytest.mark.parametrize("key,value", CHANGES, ids=[c[0] for c in CHANGES])
def test_a_changed_parameter_changes_the_image(renderer, key, value):
    # phi_step 3 leaves the fibers room to move in their slots, so angular jitter shows
    base = {"scene.count": 8, "scene.segments": 3, "fibers.phi_step": 3.0}
    p, scene, cam = setup(renderer, base)
    before = renderer.render(p, cam, SIZE).color
    camera = {"azimuth": value} if key == "camera.azimuth" else None
    p2, scene2, cam2 = setup(renderer, {**base, key: value}, camera)
    after = renderer.render(p2, cam2, SIZE).color
    changed = np.any(before != after, -1).mean()
    assert changed > 0.002, f"{key} = {value!r} changed only {changed:.4%} of the pixels"


LOOKS = [{}, {"look.model": "marschner"}, {"look.model": "marschner", "look.color_mode": "melanin",
                                             "look.melanin": 1.0, "look.self_shadow": "traced"},
         {"shape.curl_amplitude": 0.5, "shape.twist": 2.0, "shape.ellipsoid": 1.0, "look.exposure": 10.0}]


@pytest.mark.parametrize("mode", ["fast", "exact", "brute"])
@pytest.mark.parametrize("look", range(len(LOOKS)))
def test_float_outputs_are_finite(renderer, mode, look):
    p, scene, cam = setup(renderer, {"scene.taper": 0.7, "scene.segments": 4, "scene.bend": 90.0,
                                     "fibers.radial_jitter": 1.0, "fibers.angular_jitter": 1.0, **LOOKS[look]})
    frame = renderer.render(p, cam, SIZE, outputs=("geom", "cost", "ids", "color"), mode=mode)
    assert frame.hit.any() and np.any(frame.color[frame.hit] > 0)
    assert np.isfinite(frame.geom).all() and np.isfinite(frame.cost).all()
    n = frame.geom[..., :3][frame.hit]
    assert np.allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-3)
    assert (frame.geom[..., 3][frame.hit] > 0).all()


def test_shader_errors_name_the_glsl_file_and_line(ctx, tmp_path):
    root = tmp_path / "glsl"
    shutil.copytree(glsl_root(), root)
    target = root / "fibers" / "traverse.glsl"
    lines = target.read_text().splitlines()
    where = next(i for i, line in enumerate(lines) if "gTests++;" in line)
    lines[where] = "    gTests += undefined_thing;"
    target.write_text("\n".join(lines) + "\n")
    renderer = Renderer(ctx, ProgramCache(root))
    p, scene, cam = setup(renderer, {})
    with pytest.raises(ShaderCompileError) as info:
        renderer.render(p, cam, (8, 8))
    assert f"glsl/fibers/traverse.glsl:{where + 1}" in str(info.value)
    assert ctx.error in ("GL_NO_ERROR", "GL_INVALID_OPERATION")  # clear the slate for the next test


# The first three are the exact traversal's unfiltered shading, recorded before the filter existed: they keep
# quality.filter = off (the default since #16 is coverage). carpet-filtered is the default look of the first.
OFF = {"quality.filter": "off"}
GOLDEN_SCENES = {
    "carpet-exact": ({**OFF}, {}),
    "single-side": ({"scene.generator": "single", "scene.radius": 1.0, "scene.length": 4.0,
                     "fibers.rings": 6, "fibers.phi_step": 4.0, "fibers.fiber_radius": 0.03, **OFF},
                    {"elevation": 5.0}),
    "bent-tapered": ({"scene.count": 6, "scene.segments": 5, "scene.bend": 80.0, "scene.taper": 0.6, **OFF}, {}),
    "carpet-filtered": ({"quality.filter": "coverage"}, {}),
}
# per-golden tolerance: fraction of pixels allowed to differ by more than 8/255 (llvmpipe is exact
# run to run; different LLVM versions may round atan() differently at fiber edges)
TOLERANCE = {"carpet-exact": 0.002, "single-side": 0.002, "bent-tapered": 0.002, "carpet-filtered": 0.002}


@pytest.mark.parametrize("name", sorted(GOLDEN_SCENES))
def test_goldens(gl, renderer, regen_goldens, name):
    require_llvmpipe(gl)
    values, camera = GOLDEN_SCENES[name]
    p, scene, cam = setup(renderer, values, camera)
    img = renderer.render(p, cam, (240, 144)).color
    check_golden(gl, img, GOLDENS / f"{name}.png", TOLERANCE[name], regen_goldens, name)


def test_frame_gpu_bytes_counts_what_a_frame_allocates(renderer):
    """vfiber info and the viewer report frame_gpu_bytes beside the scene bytes (issue 12): it must be what
    the renderer's per-pixel targets really take, walk state, the filtered mode's images and the proxies'
    nearest hit included."""
    from app.params import Params
    from app.render.camera import Camera
    from app.render.renderer import frame_gpu_bytes
    from app.scene.generators import build_scene

    p = Params().replace(**{"quality.visibility": "walk", "quality.filter": "coverage"})
    scene = build_scene(p)
    renderer.set_scene(scene)
    size = (64, 36)
    cam = Camera.from_params(p, scene, aspect=size[0] / size[1])
    renderer.render(p, cam, size, outputs=("color", "ids", "cost"))
    renderer.render(p.replace(**{"quality.visibility": "proxies", "quality.filter": "off"}), cam, size)
    attachments = {}
    for (s, kind), target in renderer._targets.items():
        if s != size or kind == "proxy cost" or not hasattr(target, "color_attachments"):
            continue
        for a in [*target.color_attachments, target.depth_attachment]:
            if a is not None:
                attachments[(type(a).__name__, a.glo)] = a      # textures and renderbuffers number apart
    per_byte = {"f1": 1, "u1": 1, "u4": 4, "i4": 4, "f4": 4, "f2": 2}
    total = sum(a.width * a.height * a.components * per_byte[a.dtype] for a in attachments.values())
    assert total == frame_gpu_bytes(size), (total, frame_gpu_bytes(size))
