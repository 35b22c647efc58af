"""Blender/Cycles verification harness for exported OSL shaders.

Compile an OSL shader with the OSL compiler bundled in Blender's ``bpy`` module, inspect its parameters with
the bundled ``oslquery``, and render it in Cycles (CPU, OSL shading system) on mesh cylinders seen through an
OpenGL-style pinhole camera, so that tests can compare the exported look with the GLSL preview.

``bpy`` (the ``[blender]`` extra, ``bpy==5.0.1``, Python 3.11) is imported lazily: importing this module
never needs it.

API
===

``blender_available() -> (bool, reason)``
    Whether ``import bpy`` works and its Cycles has OSL. Cached. Imports bpy into this process.
``compile_osl(src_path, oso_path)``
    Compile ``.osl`` to ``.oso`` in this process. Raises :class:`OSLCompileError` whose ``messages`` are the
    compiler's lines (``ERROR: /path/x.osl:4: error: Syntax error: syntax error``), ``lines`` the line numbers.
``query_osl(path) -> dict``
    ``{"name", "type", "metadata", "parameters": {name: {"name", "type", "default", "output", "closure",
    "arraylen", "metadata": {label/min/max/help/widget...}}}}`` in declaration order. ``type`` is OSL's spelling
    (``float``, ``color``, ``point``, ``float[3]``, ``closure color``...). A ``.osl`` path is compiled first.
``render_cylinders_with_osl(osl_path, cylinders, camera, size=(256, 256), samples=8, params=None, ...) -> dict``
    ``{"rgba": float32 (H, W, 4), "seconds": Cycles render time, "setup_seconds", "total_seconds",
    "sockets": {identifier: value}, "errors", "log", "device"}``. See its docstring for the options.
``pinhole_rays(camera, size)`` / ``analytic_cylinder_mask(cylinders, camera, size, keep=None)``
    numpy reference of the same camera and (exact, round) capped cylinders, for checking renders; ``keep``
    selects opaque surface points in object space (the reference of a shader that is partly transparent).
``cylinder_frame(p0, p1)``
    The object frame each cylinder gets in Blender (what ``transform("object", P)`` sees).

Process model (decision)
========================

Compiling and querying run in the calling process (cheap, stateless; ~0.8 s once for ``import bpy``, then
milliseconds per shader). Rendering runs by default in a child process, ``python -m app.export.blender
--render job.json``: bpy is a whole Blender (one global Main database, the Cycles/OSL shading system with its
shader cache, registered add-ons, its own thread pools); a crash in that native code would take pytest down
with it, and a fresh process per render guarantees that nothing leaks from one render into the next. The
price is ~1 s (``import bpy`` and start-up) per render. ``isolate=False`` renders in this process instead:
repeated in-process renders of different shaders after ``read_factory_settings(use_empty=True)`` work, and
give bit-identical pixels to isolated ones (checked); use it for batches. Errors come back as the same
exceptions either way (the child reports them in ``result.json``).

Scene conventions
=================

* World units, Z up (Blender's). Camera ``dict(position, target, up, fov_deg[, near, far])``: ``fov_deg`` is the
  *vertical* field of view, aspect = width / height, square pixels, no lens shift -- the same pinhole as
  ``glm::perspective(fov, w/h, near, far)`` with a ``lookAt(position, target, up)`` view matrix (Blender:
  ``sensor_fit = 'VERTICAL'``, ``angle_y = fov``). Verified against :func:`analytic_cylinder_mask`: silhouette
  IoU > 0.98 for a tilted cylinder, off-axis camera, 320x192.
* ``rgba[0]`` is the **top** image row (like PIL; flip an OpenGL ``glReadPixels`` buffer to compare). Values are
  linear, scene-referred, *premultiplied* by alpha (Cycles' EXR output, 32-bit float): no view transform, no
  sRGB encoding. Coverage mask: ``rgba[..., 3] > 0.5``.
* Lighting: only a uniform world of radiance ``world_color`` (default white 1.0); no lamps. Under it a convex
  object with ``albedo * diffuse(N)`` renders exactly ``albedo`` (noise free), which makes colour checks easy.
* Each cylinder ``(p0, p1, radius)`` or ``(p0, p1, radius, x_axis)`` is its own mesh object (``segments`` sides,
  default 32, smooth-shaded sides, flat caps unless ``caps=False``) sharing one material: a Script node
  (mode ``EXTERNAL``, pointing at the compiled ``.oso``) whose first closure output feeds the Material Output
  Surface. The **object frame**: origin at ``p0``, local +Z along ``p1 - p0`` (so object-space ``z`` runs over
  ``[0, length]``), local +X = ``x_axis`` or, by default, Duff et al. 2017's ``orthonormal_x(z)`` (the same
  frame x as ``app.scene.containers``), Y = Z x X. No scale: object space is metric. The mesh carries
  a UV map ``UVMap`` (u = angle / 2pi from +X toward +Y, v = z / length on the side; caps map the disc to
  [0,1]^2) and constant float point attributes ``vf_radius``, ``vf_length``, ``vf_index`` (container index).
* Deterministic: fixed seed, no animated seed, no adaptive sampling, no denoising; the same job gives
  bit-identical pixels. Few bounces (``max_bounces=2``), ``transparent_max_bounces=64``.

Findings: what OSL sees in Cycles (Blender 5.0.1, OSL 1.14.7, CPU) -- measured by probe renders
=================================================================================================

Probe shaders emitted ``emission() * (value + 10)`` (``emission()`` has radiance = its weight, no pi) and
the pixel was read back; the ones that matter are locked in by ``tests/osl_fixtures/conventions.osl``.

* **P** lies on the flat mesh facets (up to ``r (1 - cos(pi/segments))`` inside the round cylinder, 0.5 % of r
  at 32 segments); **N** is the smooth interpolated normal, **Ng** the facet normal. Both world space
  ("common" == "world").
* **I points from P toward the viewer** (Cycles' "Incoming"), the *opposite* of the OSL spec: for a front
  face ``dot(I, N) > 0``, so the stock idioms ``faceforward(N, I)`` and ``reflect(I, N)`` come out inverted.
  The ray direction is ``-I``. ``getattribute("path:ray_length", t)`` works: the ray origin is ``P + t * I``
  (for camera rays that is on the near clip distance, not the eye). To ray-cast the *true* round container
  (as the GLSL preview does), intersect the line ``P + s * (-I)`` (s may be negative) with the analytic
  cylinder in object space; this is valid for every ray type (camera, shadow, bounce), unlike using the eye.
* **Object space works per object**: ``transform("object", P)`` (== ``transform("world", "object", P)``),
  ``transform("object", "world", vector(0, 0, 1))`` = the container axis, ``transform("object", "world",
  point(0))`` = p0, ``getmatrix("object", "world", M)`` (returns 1; translation in ``M[3][0..2]``, row-vector
  layout), ``getattribute("object:location", p)``. Verified with two differently oriented cylinders sharing
  one material, and Cycles applying the transform to the mesh data does not hide it.
* **u, v are the triangle's barycentrics**, not a UV map (``dPdu``/``dPdv`` are triangle edges). UVs and other
  mesh attributes come through ``getattribute(name, ...)`` -- but **only when a non-OSL node of the material
  requests them**: Cycles exports an attribute only on such a request (a ``getattribute`` in a script node is
  not one; an unconnected Attribute node is pruned). The harness therefore feeds Attribute nodes into AOV
  Outputs (``attributes=``); then ``getattribute("UVMap", point)``, ``getattribute("vf_radius", float)`` etc.
  work. ``geom:uv`` and ``geom:undisplaced`` are *not* found even then (use the map's name); ``geom:generated``
  (object bounding box mapped to [0,1]^3) is found once a Texture Coordinate node uses it.
  ``geom:name`` (object name), ``geom:is_smooth``, ``object:random``, ``object:index`` work without a request.
  Object custom properties: ``getattribute("\\001object:NAME", f)`` (a \\001 byte before ``object:``) when an
  Attribute node of type OBJECT asks for NAME (``attributes=["object:NAME"]``, ``object_props=``).
* Spaces: ``"camera"`` is Cycles' camera space, **+Z forward**, X right, Y up (OpenGL eye space looks down -Z);
  ``transform("camera", "world", point(0))`` is the eye. ``"raster"`` = pixels with the origin at the
  *bottom*-left and pixel centres at .5 (== ``gl_FragCoord.xy``); ``"NDC"`` = raster / size in [0, 1].
  ``getattribute("camera:resolution"/"camera:fov")`` are not available to surface shaders.
* Derivatives work (``Dx(P)``, ``Dy(P)``, ``area(P)``, ``calculatenormal``). ``time`` is 0.5, ``Ps`` is 0,
  ``backfacing()`` and ``raytype("camera")`` work.
* **trace() is supported** on CPU: ``trace(P, -N)`` from the front hits the back wall, and
  ``getmessage("trace", "hitdist" / "P" / "N" / "geom:name", ...)`` answer (the N of a back face comes back
  flipped toward the ray). ``pointcloud_search`` compiles and silently returns 0 (no point clouds).
  ``dict_find``, ``noise``, ``spline`` work. ``texture()`` of a missing file returns magenta (1, 0, 1),
  silently.
* **transparent() + film_transparent gives the mask**: alpha = 1 - the fraction transmitted through every
  surface on the ray (a closed cylinder has two), ``w * transparent()`` is partial. Each surface crossed costs
  one transparent bounce; when ``transparent_max_bounces`` runs out the pixel turns **opaque black** (alpha
  1), so N overlapping transparent containers need 2N (default 64). ``holdout()`` gives alpha 0 *and* cuts
  out whatever is behind. A transparent+diffuse mix is resolved stochastically (noisy alpha).
* **Closures Cycles does not implement** (they compile, then print ``ERROR: Closure 'x' is not supported by
  the current renderer`` at render time and render as opaque black; ``strict=True`` turns that into
  :class:`BlenderRenderError`): ``phong``, ``ward``, ``debug``, ``subsurface`` (OSL's), ``ambient_occlusion``,
  and the MaterialX-style ``transparent_bsdf``, ``translucent_bsdf``, ``chiang_hair_bsdf``. Supported among
  others: ``diffuse``, ``oren_nayar``, ``translucent``, ``microfacet``, ``reflection``, ``refraction``,
  ``transparent``, ``holdout``, ``emission``, ``background``, ``oren_nayar_diffuse_bsdf``,
  ``burley_diffuse_bsdf``, ``dielectric_bsdf``, ``conductor_bsdf``, ``generalized_schlick_bsdf``,
  ``subsurface_bssrdf``, ``sheen_bsdf``, ``uniform_edf``, ``layer`` and, from ``stdcycles.h``,
  ``hair_reflection``, ``hair_transmission``, ``hair_chiang``, ``hair_huang``, ``microfacet_f82_tint``,
  ``bssrdf``, ``diffuse_toon``, ``ashikhmin_velvet``, ``sheen``, ``diffuse_ramp``, ``phong_ramp``.
* Parameter names must not shadow globals (``v``, ``u``, ``P``, ``N``, ``I``...): ``"v" already declared``.
* Script-node sockets: identifier = OSL parameter name, label = ``[[string label]]``. Setting a Script
  node's ``filepath`` while the engine is Cycles already rebuilds its sockets -- which imports ``oslquery``,
  so Blender's bundled site-packages must be on ``sys.path`` first (else a ``ModuleNotFoundError`` is printed
  and the node keeps no sockets).

Other things that bite
======================

* ``_cycles.osl_compile`` returns a bool; the messages go to C stderr only (captured here at fd level).
  Blender 5.0.1's compiler reports **line numbers one too high** for an absolute source path under the
  current directory; :func:`compile_osl` hands it a relative path (see ``_compiler_path``).
* ``oslquery.OSLQuery(path)`` is falsy on failure and prints the reason to stderr; ``shadername()`` and
  ``shadertype()`` are methods, ``nparams``/``parameters``/``metadata`` attributes; a closure parameter's
  type prints as ``pointer``.
* ``ob.matrix_world = nested_list`` is read column-major (transposed); build a ``mathutils.Matrix``.
* ``pip install bpy==5.0.1`` pins ``numpy<2`` (it downgraded the venv from 2.4 to 1.26.4); ~0.9 GB installed.
* Under a uniform world a lone convex diffuse object renders exactly its albedo (zero variance); samples
  that bounce onto another cylinder are dark with ``max_bounces=2`` / ``diffuse_bounces=1``.

Timings (2-core CPU, no GPU): ``import bpy`` 0.7-0.8 s; compile of a small shader 0.01-0.03 s; query 0.01 s;
Cycles render at 256x256, 8 samples, one or two cylinders: 0.15-0.6 s (incl. OSL JIT), scene setup ~0.1 s;
an isolated render call 1.2-2.5 s wall in all.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from app.errors import VfiberError

__all__ = [
    "BlenderUnavailable", "OSLCompileError", "OSLQueryError", "BlenderRenderError",
    "blender_available", "compile_osl", "query_osl", "render_cylinders_with_osl",
    "pinhole_rays", "analytic_cylinder_mask", "cylinder_frame", "orthonormal_x",
]

_REPO_ROOT = Path(__file__).resolve().parents[2]
_FD_LOCK = threading.Lock()
#: mesh attributes every render makes visible to ``getattribute`` (see ``_request_attributes``)
DEFAULT_ATTRIBUTES = ("UVMap", "vf_radius", "vf_length", "vf_index", "generated")


class BlenderUnavailable(VfiberError, RuntimeError):
    """``bpy`` cannot be imported (or its Cycles lacks OSL)."""


class OSLCompileError(VfiberError, RuntimeError):
    """The OSL compiler rejected a shader. ``messages``: the compiler's output lines; ``lines``: the source line
    numbers it names; ``path``: the source file."""

    def __init__(self, path: str, messages: Sequence[str]):
        self.path = str(path)
        self.messages = list(messages)
        self.lines = [int(m.group(1)) for m in (re.search(r"\.osl:(\d+):", s) for s in self.messages) if m]
        body = "\n".join(self.messages) or "(the compiler printed nothing)"
        super().__init__(f"OSL compilation of {self.path} failed:\n{body}")


class OSLQueryError(VfiberError, RuntimeError):
    """oslquery could not read a compiled shader."""


class BlenderRenderError(VfiberError, RuntimeError):
    """The Cycles render failed; the message carries the tail of Blender's output."""


# --------------------------------------------------------------------------------------------------------------
# bpy access


def _oslquery_path(bpy) -> str:
    return os.path.join(bpy.utils.resource_path("LOCAL"), "python", "lib",
                        f"python{sys.version_info.major}.{sys.version_info.minor}", "site-packages")


def _bpy():
    """Import bpy and _cycles, put the bundled oslquery on sys.path. Raises BlenderUnavailable."""
    try:
        import bpy  # noqa: F401  (heavy: a whole Blender)
        import _cycles
    except Exception as e:  # ImportError, or a missing system library (OSError) inside bpy
        raise BlenderUnavailable(f"cannot import bpy ({type(e).__name__}: {e}); "
                                 "install the [blender] extra: pip install 'bpy==5.0.1' (Python 3.11)") from e
    path = _oslquery_path(bpy)
    if path not in sys.path:
        # appended, not prepended: Blender's bundled site-packages also holds OpenImageIO, MaterialX, pxr...
        sys.path.append(path)
    return bpy, _cycles


@functools.lru_cache(maxsize=1)
def blender_available() -> tuple[bool, str]:
    """(True, "bpy 5.0.1, OSL 1.14.7") when bpy imports and has OSL; else (False, why)."""
    import importlib.util
    if importlib.util.find_spec("bpy") is None:
        return False, "bpy is not installed (pip install 'vfiber[blender]', i.e. bpy==5.0.1 on Python 3.11)"
    try:
        bpy, _cycles = _bpy()
    except BlenderUnavailable as e:
        return False, str(e)
    if not _cycles.with_osl:  # a module attribute (bool), not a function
        return False, f"bpy {bpy.app.version_string} was built without OSL"
    try:
        import oslquery  # noqa: F401
    except ImportError as e:
        return False, f"bpy's bundled oslquery is not importable from {_oslquery_path(bpy)}: {e}"
    osl = ".".join(x.strip() for x in str(_cycles.osl_version_string).split(","))  # " 1, 14,  7"
    return True, f"bpy {bpy.app.version_string}, OSL {osl}"


@contextlib.contextmanager
def _capture_fds(out: list[str]):
    """Capture what C code writes to file descriptors 1 and 2 (the OSL compiler and oslquery print their errors
    there, not through Python and not through a return value). Appends the text to ``out``."""
    libc = ctypes.CDLL(None)
    with _FD_LOCK:
        for s in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                s.flush()
        libc.fflush(None)
        saved = {fd: os.dup(fd) for fd in (1, 2)}
        tmp = tempfile.TemporaryFile()
        try:
            for fd in (1, 2):
                os.dup2(tmp.fileno(), fd)
            yield
        finally:
            libc.fflush(None)
            for fd, dup in saved.items():
                os.dup2(dup, fd)
                os.close(dup)
            tmp.seek(0)
            out.append(tmp.read().decode("utf-8", "replace"))
            tmp.close()


# --------------------------------------------------------------------------------------------------------------
# compile / query


def compile_osl(src_path: str | os.PathLike, oso_path: str | os.PathLike) -> None:
    """Compile ``src_path`` (.osl) to ``oso_path`` (.oso) with Blender's OSL compiler (``stdosl.h`` and Cycles'
    ``stdcycles.h`` are on its include path). Raises :class:`OSLCompileError` with the compiler's messages."""
    _, _cycles = _bpy()
    src, dst = os.fspath(src_path), os.fspath(oso_path)
    if not os.path.isfile(src):
        raise OSLCompileError(src, [f"ERROR: input file {src!r} not found"])
    with contextlib.suppress(FileNotFoundError):
        os.remove(dst)  # so a stale .oso never passes for a fresh one
    text: list[str] = []
    given = _compiler_path(src)
    with _capture_fds(text):
        ok = bool(_cycles.osl_compile(given, dst))
    # name the file as the caller did, not by the relative spelling handed to the compiler
    messages = [ln.replace(f"{given}:", f"{src}:") for ln in "".join(text).splitlines() if ln.strip()]
    if not ok or not os.path.isfile(dst):
        raise OSLCompileError(src, messages)
    for ln in messages:  # warnings, if the compiler printed any, are passed on to Python's warnings
        import warnings
        warnings.warn(f"oslc: {ln}", stacklevel=2)


def _compiler_path(src: str) -> str:
    """The spelling of ``src`` to hand to the compiler. Blender 5.0.1's OSL compiler reports line numbers one
    too high when given an *absolute* path that lies under the current directory (it prints the path made
    relative); a relative path, or an absolute one outside the cwd, is reported right. So pass it relative."""
    try:
        return os.path.relpath(src)
    except ValueError:  # another drive (Windows), or no cwd
        return src


def _py(value):
    if isinstance(value, tuple):
        return [_py(v) for v in value]
    return value


def query_osl(path: str | os.PathLike) -> dict:
    """Shader name, type, shader metadata and parameters (in declaration order) of a compiled shader; a
    ``.osl`` path is compiled to a temporary ``.oso`` first."""
    _bpy()
    path = os.fspath(path)
    if path.endswith(".osl"):
        with tempfile.TemporaryDirectory(prefix="vfiber-osl-") as d:
            oso = os.path.join(d, Path(path).stem + ".oso")
            compile_osl(path, oso)
            return query_osl(oso)
    import oslquery
    text: list[str] = []
    with _capture_fds(text):
        q = oslquery.OSLQuery(path)
    if not q:
        raise OSLQueryError(f"oslquery cannot read {path}: {''.join(text).strip() or q.geterror()}")
    params: dict[str, dict] = {}
    for p in q.parameters:
        typ = "closure color" if p.isclosure else str(p.type)
        params[p.name] = {
            "name": p.name,
            "type": typ,
            "default": _py(p.value),
            "output": bool(p.isoutput),
            "closure": bool(p.isclosure),
            "arraylen": -1 if p.varlenarray else int(p.type.arraylen),
            "metadata": {m.name: _py(m.value) for m in p.metadata},
        }
    return {"name": q.shadername(), "type": q.shadertype(),
            "metadata": {m.name: _py(m.value) for m in q.metadata}, "parameters": params}


# --------------------------------------------------------------------------------------------------------------
# geometry and camera (pure numpy; the reference the renders are checked against)


def orthonormal_x(z) -> np.ndarray:
    """Unit vector perpendicular to unit ``z`` (Duff et al. 2017); the default object x axis of a cylinder."""
    z = np.asarray(z, dtype=np.float64)
    sign = 1.0 if z[2] >= 0.0 else -1.0
    a = -1.0 / (sign + z[2])
    b = z[0] * z[1] * a
    return np.array([1.0 + sign * z[0] ** 2 * a, sign * b, -sign * z[0]])


def cylinder_frame(p0, p1, x_axis=None) -> tuple[np.ndarray, float]:
    """(4x4 object-to-world matrix, length) of the object a cylinder from p0 to p1 becomes: origin p0, +Z toward
    p1, +X = ``x_axis`` made perpendicular (default :func:`orthonormal_x`), Y = Z x X."""
    p0, p1 = np.asarray(p0, np.float64), np.asarray(p1, np.float64)
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    if not length > 0:
        raise ValueError(f"degenerate cylinder: p0 == p1 == {p0.tolist()}")
    z = axis / length
    if x_axis is None:
        x = orthonormal_x(z)
    else:
        x = np.asarray(x_axis, np.float64)
        x = x - np.dot(x, z) * z
        if np.linalg.norm(x) < 1e-9:
            raise ValueError(f"x_axis {list(x_axis)} is parallel to the cylinder axis")
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, y, z, p0
    return m, length


def _camera_basis(camera: Mapping) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    pos = np.asarray(camera["position"], np.float64)
    fwd = np.asarray(camera["target"], np.float64) - pos
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, np.asarray(camera.get("up", (0, 0, 1)), np.float64))
    if np.linalg.norm(right) < 1e-9:
        raise ValueError("camera up is parallel to the view direction")
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    return pos, right, up, fwd


def pinhole_rays(camera: Mapping, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Origin (3,) and unit directions (H, W, 3) through pixel centres, row 0 at the top, of the OpenGL pinhole
    ``perspective(fov_deg vertical, W/H) * lookAt(position, target, up)``."""
    w, h = size
    pos, right, up, fwd = _camera_basis(camera)
    t = math.tan(math.radians(camera["fov_deg"]) / 2)
    xs = (2 * (np.arange(w) + 0.5) / w - 1) * t * (w / h)
    ys = (1 - 2 * (np.arange(h) + 0.5) / h) * t
    d = fwd + xs[None, :, None] * right + ys[:, None, None] * up
    return pos, d / np.linalg.norm(d, axis=-1, keepdims=True)


def _cylinder_parts(c) -> tuple[Any, Any, float, Any]:
    if len(c) == 3:
        p0, p1, r = c
        return p0, p1, float(r), None
    p0, p1, r, x = c
    return p0, p1, float(r), x


def analytic_cylinder_mask(cylinders: Iterable, camera: Mapping, size: tuple[int, int], caps: bool = True,
                           near: float = 0.0, keep=None) -> np.ndarray:
    """Boolean (H, W) coverage of exact round cylinders (capped unless ``caps=False``) by :func:`pinhole_rays`.

    ``keep(points, index) -> bool array``, given object-space surface points (..., 3) of cylinder ``index``
    (the frame of :func:`cylinder_frame`), selects the opaque ones; a pixel is covered when any surface point
    on its ray is kept. This is the exact reference of a shader that is ``transparent()`` where ``keep`` is
    false (rays pass through transparent surfaces, so entry *and* exit points count)."""
    o, d = pinhole_rays(camera, size)
    hit = np.zeros(d.shape[:2], bool)
    for index, c in enumerate(cylinders):
        p0, p1, r, xa = _cylinder_parts(c)
        m, length = cylinder_frame(p0, p1, xa)
        rot = m[:3, :3]
        lo = rot.T @ (o - m[:3, 3])
        ld = d @ rot  # rows of d in the object frame
        dx, dy, dz = ld[..., 0], ld[..., 1], ld[..., 2]
        a = dx * dx + dy * dy
        b = 2 * (lo[0] * dx + lo[1] * dy)
        cc = lo[0] ** 2 + lo[1] ** 2 - r * r
        disc = b * b - 4 * a * cc
        ok = (disc >= 0) & (a > 1e-300)
        sq = np.sqrt(np.where(ok, disc, 0))
        aa = np.where(a > 1e-300, a, 1)
        cands = []
        for t in ((-b - sq) / (2 * aa), (-b + sq) / (2 * aa)):
            z = lo[2] + t * dz
            cands.append((ok & (t > near) & (z >= 0) & (z <= length), t))
        if caps:
            with np.errstate(divide="ignore", invalid="ignore"):
                for zc in (0.0, length):
                    t = (zc - lo[2]) / dz
                    x, y = lo[0] + t * dx, lo[1] + t * dy
                    cands.append((np.isfinite(t) & (t > near) & (x * x + y * y <= r * r), t))
        for valid, t in cands:
            if keep is not None:
                pts = lo + np.where(valid, t, 0)[..., None] * ld
                valid = valid & np.asarray(keep(pts, index), bool)
            hit |= valid
    return hit


# --------------------------------------------------------------------------------------------------------------
# rendering


def render_cylinders_with_osl(osl_path: str | os.PathLike, cylinders: Sequence, camera: Mapping,
                              size: tuple[int, int] = (256, 256), samples: int = 8,
                              params: Mapping[str, Any] | None = None, *, segments: int = 32, caps: bool = True,
                              world_color=(1.0, 1.0, 1.0), max_bounces: int = 2,
                              transparent_bounces: int = 64, filter_width: float = 1.5, seed: int = 0,
                              output: str | None = None, strict: bool = True,
                              attributes: Sequence[str] = DEFAULT_ATTRIBUTES,
                              object_props: Sequence[Mapping[str, float]] | None = None, isolate: bool = True,
                              timeout: float = 600.0) -> dict:
    """Render ``osl_path`` (.osl, compiled first, or .oso) as the surface of the given cylinders in Cycles.

    cylinders: ``[(p0, p1, radius)]`` or ``[(p0, p1, radius, x_axis)]`` in world units (Z up); see the module
    docstring for the object frame each one gets. camera: ``dict(position, target, up, fov_deg, near=0.01,
    far=1e4)``, ``fov_deg`` vertical. size: (width, height). params: script-node input values by OSL parameter
    name (colours may have 3 components). output: name of the closure output to use (default: the first).
    attributes: mesh attributes made visible to ``getattribute`` (see ``_request_attributes``); object_props:
    per cylinder ``{name: float}`` custom properties, readable as ``getattribute("\\001object:name", f)`` when
    ``"object:name"`` is in ``attributes``. strict: raise when Cycles prints an ERROR while rendering (an
    unsupported closure renders as black and is only printed). isolate: render in a child process.

    Returns ``{"rgba": float32 (H, W, 4) top row first, linear premultiplied, "seconds": time spent in the
    Cycles render (incl. OSL JIT), "setup_seconds": scene building, "total_seconds": wall time of this call
    incl. process start and import bpy, "sockets": {identifier: value} of the script node's inputs as rendered,
    "errors": ERROR lines Cycles printed, "log": all it printed while rendering, "device": str}``.
    Raises OSLCompileError, ValueError (bad camera/params/output), BlenderRenderError.
    """
    t0 = time.perf_counter()
    job = {
        "osl_path": os.fspath(Path(osl_path).resolve()),
        "cylinders": [[list(map(float, p0)), list(map(float, p1)), r] + ([list(map(float, x))] if x is not None
                                                                       else [])
                      for p0, p1, r, x in (_cylinder_parts(c) for c in cylinders)],
        "camera": {k: (list(map(float, v)) if isinstance(v, (list, tuple, np.ndarray)) else v)
                   for k, v in dict(camera).items()},
        "size": [int(size[0]), int(size[1])], "samples": int(samples),
        "params": {k: (list(map(float, v)) if isinstance(v, (list, tuple, np.ndarray)) else v)
                   for k, v in dict(params or {}).items()},
        "segments": int(segments), "caps": bool(caps), "world_color": list(map(float, world_color)),
        "max_bounces": int(max_bounces), "transparent_bounces": int(transparent_bounces),
        "filter_width": float(filter_width), "seed": int(seed), "output": output, "strict": bool(strict),
        "attributes": list(attributes), "object_props": object_props,
    }
    for k in ("position", "target", "fov_deg"):
        if k not in job["camera"]:
            raise ValueError(f"camera needs {k!r} (have {sorted(job['camera'])})")
    if not job["cylinders"]:
        raise ValueError("no cylinders to render")
    if isolate:
        res = _render_subprocess(job, timeout)
    else:
        with tempfile.TemporaryDirectory(prefix="vfiber-render-") as d:
            res = _render_in_process(job, d)
    res["total_seconds"] = time.perf_counter() - t0
    return res


def _render_subprocess(job: dict, timeout: float) -> dict:
    with tempfile.TemporaryDirectory(prefix="vfiber-render-") as d:
        job_path = os.path.join(d, "job.json")
        with open(job_path, "w") as f:
            json.dump(job, f)
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([str(_REPO_ROOT)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH")
                                                                else []))
        try:
            proc = subprocess.run([sys.executable, "-m", "app.export.blender", "--render", job_path],
                                  capture_output=True, text=True, timeout=timeout, env=env,
                                  cwd=str(_REPO_ROOT))
        except subprocess.TimeoutExpired as e:
            raise BlenderRenderError(f"Blender render timed out after {timeout:.0f} s") from e
        log = (proc.stdout or "") + (proc.stderr or "")
        res_path = os.path.join(d, "result.json")
        if not os.path.isfile(res_path):
            raise BlenderRenderError(f"Blender render process failed (exit {proc.returncode}):\n"
                                     + "\n".join(log.splitlines()[-40:]))
        with open(res_path) as f:
            res = json.load(f)
        if not res.get("ok"):
            kind, msg = res.get("error_type"), res.get("message", "")
            if kind == "OSLCompileError":
                raise OSLCompileError(res.get("path", job["osl_path"]), res.get("messages", []))
            if kind == "ValueError":
                raise ValueError(msg)
            raise BlenderRenderError(f"{kind}: {msg}\n" + "\n".join(log.splitlines()[-40:]))
        rgba = np.load(os.path.join(d, "rgba.npy"))
        res.pop("ok")
        res["rgba"] = rgba
        return res


def _socket_value(sock):
    v = getattr(sock, "default_value", None)
    if v is None or isinstance(v, (bool, int, float, str)):
        return v
    return [float(x) for x in v]


def _render_in_process(job: dict, workdir: str) -> dict:
    """Build the scene from ``job`` in this process's bpy and render it. Returns the result dict."""
    bpy, _cycles = _bpy()
    t_setup = time.perf_counter()
    osl_path = job["osl_path"]
    if osl_path.endswith(".oso"):
        oso = osl_path
    else:
        oso = os.path.join(workdir, Path(osl_path).stem + ".oso")
        compile_osl(osl_path, oso)

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"  # before the script node exists: it asks the engine to update its sockets
    cy = scene.cycles
    cy.device = "CPU"
    cy.shading_system = True  # OSL
    cy.samples = job["samples"]
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.seed = job["seed"]
    cy.use_animated_seed = False
    cy.max_bounces = job["max_bounces"]
    cy.diffuse_bounces = min(1, job["max_bounces"])
    cy.glossy_bounces = min(1, job["max_bounces"])
    cy.transmission_bounces = job["max_bounces"]
    cy.volume_bounces = 0
    cy.transparent_max_bounces = job["transparent_bounces"]
    cy.caustics_reflective = cy.caustics_refractive = False
    cy.blur_glossy = 0.0
    cy.sample_clamp_direct = cy.sample_clamp_indirect = 0.0
    cy.pixel_filter_type = "BLACKMAN_HARRIS"
    cy.filter_width = job["filter_width"]
    render = scene.render
    render.film_transparent = True
    render.resolution_x, render.resolution_y = job["size"]
    render.resolution_percentage = 100
    render.pixel_aspect_x = render.pixel_aspect_y = 1.0
    render.use_persistent_data = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"

    world = bpy.data.worlds.new("vf_world")
    scene.world = world
    bg = next(n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeBackground")
    bg.inputs["Color"].default_value = (*job["world_color"], 1.0)
    bg.inputs["Strength"].default_value = 1.0

    mat = bpy.data.materials.new("vf_osl")
    nt = mat.node_tree
    for n in list(nt.nodes):
        if n.bl_idname != "ShaderNodeOutputMaterial":
            nt.nodes.remove(n)
    out_node = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    out_node.target = "CYCLES"
    script = nt.nodes.new("ShaderNodeScript")
    script.mode = "EXTERNAL"
    script.filepath = oso  # a .oso is loaded as is (a .osl would be compiled next to itself)
    reports: list[str] = []
    import cycles.osl as cycles_osl
    if not cycles_osl.update_script_node(script, lambda kind, msg: reports.append(f"{kind}: {msg}")):
        raise BlenderRenderError(f"could not load {oso} into a script node: {reports}")
    _request_attributes(bpy, scene, nt, job.get("attributes", DEFAULT_ATTRIBUTES))
    closures = [s for s in script.outputs if s.bl_idname == "NodeSocketShader"]
    if job["output"]:
        closures = [s for s in script.outputs if s.identifier == job["output"]]
        if not closures:
            raise ValueError(f"shader has no output {job['output']!r}; outputs: "
                             f"{[s.identifier for s in script.outputs]}")
    if not closures:
        raise ValueError(f"shader has no closure output; outputs: {[s.identifier for s in script.outputs]}")
    nt.links.new(closures[0], out_node.inputs["Surface"])
    inputs = {s.identifier: s for s in script.inputs}
    for name, value in job["params"].items():
        sock = inputs.get(name)
        if sock is None:
            raise ValueError(f"shader {Path(osl_path).name} has no input parameter {name!r}; "
                             f"inputs: {sorted(inputs)}")
        if sock.bl_idname == "NodeSocketColor" and len(value) == 3:
            value = [*value, 1.0]
        try:
            sock.default_value = value
        except (TypeError, ValueError) as e:
            raise ValueError(f"parameter {name!r} ({sock.bl_idname}) cannot take {value!r}: {e}") from e
    sockets = {ident: _socket_value(s) for ident, s in inputs.items()}

    for i, cyl in enumerate(job["cylinders"]):
        p0, p1, radius, xa = _cylinder_parts(cyl)
        matrix, length = cylinder_frame(p0, p1, xa)
        mesh = _cylinder_mesh(bpy, f"vf_cyl{i}", float(radius), length, job["segments"], job["caps"], i)
        mesh.materials.append(mat)
        ob = bpy.data.objects.new(f"vf_cyl{i}", mesh)
        ob.matrix_world = _matrix(matrix)
        props = {"vf_index": float(i)}
        if job.get("object_props"):
            props.update(job["object_props"][i])
        for k, v in props.items():
            ob[k] = v
        scene.collection.objects.link(ob)

    cam = _camera_object(bpy, job["camera"])
    scene.collection.objects.link(cam)
    scene.camera = cam

    im = render.image_settings
    im.file_format = "OPEN_EXR"
    im.color_mode = "RGBA"
    im.color_depth = "32"
    im.exr_codec = "ZIP"
    render.filepath = os.path.join(workdir, "render.exr")
    render.use_file_extension = False
    setup_seconds = time.perf_counter() - t_setup

    t = time.perf_counter()
    text: list[str] = []
    with _capture_fds(text):  # OSL runtime errors (unsupported closure...) are only printed, never raised
        bpy.ops.render.render(write_still=True)
    seconds = time.perf_counter() - t
    log = [ln for ln in "".join(text).splitlines() if ln.strip()]
    osl_errors = [ln for ln in log if "ERROR" in ln]
    if osl_errors and job.get("strict", True):
        raise BlenderRenderError("Cycles reported errors while rendering (pass strict=False to keep the image):\n"
                                 + "\n".join(osl_errors))
    if not os.path.isfile(render.filepath):
        raise BlenderRenderError(f"Cycles wrote no image to {render.filepath}")
    img = bpy.data.images.load(render.filepath)
    w, h = job["size"]
    buf = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(buf)
    bpy.data.images.remove(img)
    rgba = np.ascontiguousarray(buf.reshape(h, w, 4)[::-1])
    return {"rgba": rgba, "seconds": seconds, "setup_seconds": setup_seconds, "sockets": sockets,
            "errors": osl_errors, "log": log,
            "device": f"Cycles CPU (OSL), bpy {bpy.app.version_string}, {os.cpu_count()} cores"}


def _request_attributes(bpy, scene, nt, names: Sequence[str]) -> None:
    """Make Cycles export the named attributes so that ``getattribute(name, ...)`` in the script finds them.

    Cycles exports a mesh attribute only when a (non-OSL) node of the material asks for it; ``getattribute``
    inside a script node does not count, and unconnected nodes are pruned. So each name gets an Attribute node
    feeding an AOV Output (a sink that keeps it alive without changing the image). ``"generated"`` requests
    ``geom:generated`` through a Texture Coordinate node. A name ``object:NAME`` reads a custom property of
    the object (Attribute node type OBJECT)."""
    vl = scene.view_layers[0]
    for i, name in enumerate(names):
        if name == "generated":
            src = nt.nodes.new("ShaderNodeTexCoord").outputs["Generated"]
        else:
            at = nt.nodes.new("ShaderNodeAttribute")
            if name.startswith("object:"):
                at.attribute_type, at.attribute_name = "OBJECT", name.split(":", 1)[1]
            else:
                at.attribute_type, at.attribute_name = "GEOMETRY", name
            src = at.outputs["Vector"]
        aov = nt.nodes.new("ShaderNodeOutputAOV")
        aov.aov_name = f"vf_keep{i}"
        nt.links.new(src, aov.inputs["Color"])
        a = vl.aovs.add()
        a.name, a.type = aov.aov_name, "COLOR"


def _matrix(m: np.ndarray):
    """numpy 4x4 (rows) -> mathutils.Matrix. (Assigning nested lists to ``matrix_world`` would be read in
    Blender's column-major storage order, i.e. transposed.)"""
    import mathutils
    return mathutils.Matrix([[float(x) for x in row] for row in m])


def _cylinder_mesh(bpy, name: str, radius: float, length: float, n: int, caps: bool, index: int):
    """Object-space cylinder: rim i at angle 2 pi i / n from +X toward +Y, z in [0, length]. Caps get their own
    vertices so the smooth side normals stay radial and the cap normals axial."""
    ang = 2 * np.pi * np.arange(n) / n
    ring = np.stack([radius * np.cos(ang), radius * np.sin(ang)], 1)
    verts = [(x, y, 0.0) for x, y in ring] + [(x, y, length) for x, y in ring]
    faces = [(i, (i + 1) % n, n + (i + 1) % n, n + i) for i in range(n)]
    uvs = [[(i / n, 0.0), ((i + 1) / n, 0.0), ((i + 1) / n, 1.0), (i / n, 1.0)] for i in range(n)]
    if caps:
        base = len(verts)
        verts += [(x, y, 0.0) for x, y in ring] + [(x, y, length) for x, y in ring]
        faces.append(tuple(base + i for i in reversed(range(n))))          # bottom, normal -Z
        faces.append(tuple(base + n + i for i in range(n)))                # top, normal +Z
        disc = [(0.5 + 0.5 * x / radius, 0.5 + 0.5 * y / radius) for x, y in ring]
        uvs.append([disc[i] for i in reversed(range(n))])
        uvs.append(disc)
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    side = np.zeros(len(faces), bool)
    side[:n] = True
    mesh.polygons.foreach_set("use_smooth", side)  # smooth sides, flat caps
    uv = mesh.uv_layers.new(name="UVMap")
    flat = np.array([c for poly in uvs for c in poly], np.float32).ravel()
    uv.data.foreach_set("uv", flat)  # loops are in face order, as given to from_pydata
    for attr, val in (("vf_radius", radius), ("vf_length", length), ("vf_index", float(index))):
        a = mesh.attributes.new(attr, "FLOAT", "POINT")
        a.data.foreach_set("value", np.full(len(verts), val, np.float32))
    mesh.update()
    return mesh


def _camera_object(bpy, camera: Mapping):
    pos, right, up, fwd = _camera_basis(camera)
    cam = bpy.data.cameras.new("vf_camera")
    cam.type = "PERSP"
    cam.sensor_fit = "VERTICAL"  # angle_y is the vertical fov whatever the aspect, as in OpenGL
    cam.angle_y = math.radians(camera["fov_deg"])
    cam.shift_x = cam.shift_y = 0.0
    cam.clip_start = float(camera.get("near", 0.01))
    cam.clip_end = float(camera.get("far", 1e4))
    ob = bpy.data.objects.new("vf_camera", cam)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, up, -fwd, pos  # Blender cameras look down local -Z
    ob.matrix_world = _matrix(m)
    return ob


# --------------------------------------------------------------------------------------------------------------
# command line: the child process of an isolated render, and debugging helpers


def _main(argv: Sequence[str] | None = None) -> int:
    import argparse
    ap = argparse.ArgumentParser(prog="python -m app.export.blender", description=__doc__.split("\n\n")[0])
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--render", metavar="JOB_JSON", help="render a job; writes result.json and rgba.npy beside it")
    g.add_argument("--compile", nargs=2, metavar=("SRC_OSL", "DST_OSO"))
    g.add_argument("--query", metavar="OSO_OR_OSL")
    g.add_argument("--check", action="store_true", help="print whether bpy/Cycles/OSL are usable")
    a = ap.parse_args(argv)
    if a.check:
        ok, why = blender_available()
        print(why)
        return 0 if ok else 1
    if a.compile:
        try:
            compile_osl(*a.compile)
        except OSLCompileError as e:
            print(e, file=sys.stderr)
            return 1
        return 0
    if a.query:
        print(json.dumps(query_osl(a.query), indent=2))
        return 0
    job_path = os.path.abspath(a.render)
    d = os.path.dirname(job_path)
    with open(job_path) as f:
        job = json.load(f)
    res: dict[str, Any]
    try:
        res = _render_in_process(job, d)
        np.save(os.path.join(d, "rgba.npy"), res.pop("rgba"))
        res["ok"] = True
    except OSLCompileError as e:
        res = {"ok": False, "error_type": "OSLCompileError", "message": str(e), "messages": e.messages,
               "path": e.path}
    except Exception as e:  # reported to the parent, which re-raises
        import traceback
        traceback.print_exc()
        res = {"ok": False, "error_type": type(e).__name__, "message": str(e)}
    with open(os.path.join(d, "result.json"), "w") as f:
        json.dump(res, f)
    sys.stdout.flush()
    sys.stderr.flush()
    # bpy's teardown at interpreter exit is slow and occasionally noisy; the result is on disk already
    os._exit(0)


if __name__ == "__main__":
    sys.exit(_main())
