"""The ``vfiber`` command line: render, info, doctor, presets, view, bench, export-osl.

Every error a person can cause (a bad preset, a bad ``--set``, a broken groom file, no GL driver, a shader
that does not compile) ends in one line on stderr and exit status 2, never a traceback. ``VFIBER_DEBUG=1``
shows the traceback for developers.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

from .params import ParamError, Params, parse_assignment

GROOM_SUFFIXES = (".hair", ".data", ".tfx", ".ply")
OUTPUTS = ("shaded", "id", "depth", "normal", "ring", "cost")
DEFAULT_PRESET = "default"
IMAGE_SUFFIXES = (".npy", ".exr", ".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")  # what write_output writes


class UsageError(ValueError):
    """A command-line mistake the user can fix."""


# --------------------------------------------------------------------------------------------------
# parameters from the command line
# --------------------------------------------------------------------------------------------------
def resolve_params(target: str | None, assignments: list[str]) -> tuple[Params, str]:
    """Params from a preset (name or file) or a groom file, then ``--set`` overrides. Returns a label."""
    values: dict = {}
    label = "defaults"
    if target and Path(target).suffix.lower() in GROOM_SUFFIXES:
        if not Path(target).exists():
            raise UsageError(f"{target}: no such groom file")
        values = {"scene.generator": "groom", "scene.groom_file": str(Path(target).resolve())}
        label = target
    else:
        from .presets import bundled_names, find_preset

        name = target or (DEFAULT_PRESET if DEFAULT_PRESET in bundled_names() else None)
        if name:
            preset = find_preset(name)
            values = groom_relative_to_preset(dict(preset.params.values), preset.path)
            label = str(preset.path or name)
    for text in assignments:
        key, value = parse_assignment(text)
        values[key] = value
    try:
        return Params(values), label
    except ParamError as e:
        if assignments and e.source is None:
            raise ParamError(e.bare, key=e.key, source="--set") from None
        raise


def groom_relative_to_preset(values: dict, preset_path: Path | None) -> dict:
    """A relative ``scene.groom_file`` in a preset names a file beside the preset, wherever vfiber runs."""
    groom = values.get("scene.groom_file") or ""
    if groom and preset_path is not None and not Path(groom).is_absolute():
        values["scene.groom_file"] = str(Path(preset_path).parent / groom)
    return values


def scene_target(args) -> str | None:
    """The positional target or --preset; both at once must agree (else one would be silently ignored)."""
    if args.target and args.preset and args.target != args.preset:
        raise UsageError(f"two scenes given: {args.target!r} and --preset {args.preset!r}; give one")
    return args.target or args.preset


def source_of(key: str | None, assignments: list[str], label: str) -> str:
    """Where a parameter came from, for errors raised after Params were built (the renderer's)."""
    if key and any(a.split("=", 1)[0].strip() == key for a in assignments):
        return "--set"
    return label


def check_output_path(out: Path) -> None:
    """Before any work: the output's folder exists and the file may be replaced (not a folder, not
    read-only), so a long render never ends in 'cannot write'."""
    from .atomic import SaveError, save_target

    if out.suffix.lower() not in IMAGE_SUFFIXES:
        raise UsageError(f"{out}: unknown image type {out.suffix.lower()!r}; use .png, .exr or .npy")
    try:
        save_target(out)
    except SaveError as e:
        raise UsageError(f"-o {e}") from None


def check_budget(p: Params, size: tuple[int, int], allow_slow: bool, scene=None):
    """Refuse, with the estimate and how to go on, work that would take minutes or more memory than a
    frame should; before the scene is built (scene None) only its build and the frame's memory are known.
    Returns the frame's WorkEstimate once the scene is given."""
    from .render import budget
    from .units import human_bytes

    how = "add --allow-slow to run it anyway"
    if scene is None:
        seconds = budget.build_seconds(p)
        if seconds > budget.SLOW_SECONDS and not allow_slow:
            raise UsageError(f"building {p['scene.count']:,} guides x {p['scene.segments']} segments takes roughly "
                             f"{budget._duration(seconds)} before the first pixel; lower scene.count or "
                             f"scene.segments, or {how}")
        need = budget.frame_bytes(size)
        if need > budget.MAX_FRAME_BYTES and not allow_slow:
            raise UsageError(f"--size {size[0]}x{size[1]} needs about {human_bytes(need)} of memory for one frame "
                             f"(limit {human_bytes(budget.MAX_FRAME_BYTES)}); render smaller, or {how}")
        return None
    est = budget.estimate(p, scene, size)
    if est.slow and not allow_slow:
        raise UsageError(f"this frame is {est.summary()}; lower the image size, quality.supersample or the "
                         f"fiber density, or {how}")
    return est


def _gl_allocation_error(e: Exception, size: tuple[int, int]) -> UsageError | None:
    text = str(e)
    if isinstance(e, UsageError):
        return None
    if "framebuffer" in text.lower() or "out of memory" in text.lower() or isinstance(e, MemoryError):
        return UsageError(f"--size {size[0]}x{size[1]}: this OpenGL cannot allocate a frame that large "
                          f"({text.strip().splitlines()[0] if text.strip() else type(e).__name__}); render smaller")
    return None


def parse_budget(text: str) -> int:
    from .bench.__main__ import parse_bytes

    return parse_bytes(text)


def parse_size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise UsageError(f"--size {text!r}: expected WIDTHxHEIGHT, e.g. 640x360") from None
    if not (1 <= w <= 16384 and 1 <= h <= 16384):
        raise UsageError(f"--size {text!r}: width and height must be between 1 and 16384")
    return w, h


# --------------------------------------------------------------------------------------------------
# output files
# --------------------------------------------------------------------------------------------------
def output_image(frame, kind: str, p: Params) -> np.ndarray:
    from .render import debug_views as dv

    if kind == "shaded":
        return frame.color
    if kind == "id":
        return dv.fiber_id_image(frame.ids)
    if kind == "ring":
        return dv.ring_image(frame.ids, p["fibers.rings"])
    if kind == "depth":
        return dv.depth_image(frame.geom)
    if kind == "normal":
        return dv.normal_image(frame.geom)
    return dv.cost_image(frame.cost)


def output_data(frame, kind: str) -> np.ndarray:
    """Raw values for .npy/.exr: ids as uint32, the rest float32."""
    if kind == "shaded":
        return frame.color.astype(np.float32) / 255.0
    if kind in ("id", "ring"):
        return frame.ids if kind == "id" else frame.ids[..., 1:2]
    if kind == "depth":
        return frame.geom[..., 3:4]
    if kind == "normal":
        return frame.geom[..., :3]
    return frame.cost


def write_output(path: Path, frame, kind: str, p: Params) -> None:
    from PIL import Image

    from .atomic import atomic_path

    suffix = path.suffix.lower()
    with atomic_path(path) as tmp:
        if suffix == ".npy":
            with open(tmp, "wb") as f:
                np.save(f, output_data(frame, kind))
        elif suffix == ".exr":
            import OpenEXR

            data = output_data(frame, kind)
            if data.dtype != np.uint32:
                data = data.astype(np.float32)
            channels = {1: {"Y": data[..., 0]}, 3: {"RGB": data}, 4: {"RGBA": data}}[data.shape[-1]]
            header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
            OpenEXR.File(header, channels).write(str(tmp))
        elif suffix in (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp"):
            Image.fromarray(output_image(frame, kind, p)).save(tmp, format=Image.registered_extensions()[suffix])
        else:
            raise UsageError(f"{path}: unknown image type {suffix!r}; use .png, .exr or .npy")


# --------------------------------------------------------------------------------------------------
# commands
# --------------------------------------------------------------------------------------------------
def build_scene_for(p: Params):
    from .scene.generators import build_scene

    return build_scene(p)


def cmd_render(args) -> int:
    p, label = resolve_params(scene_target(args), args.set)
    if args.mode:
        p = p.replace(**{"quality.mode": args.mode})
    size = parse_size(args.size)
    out = Path(args.output_file)
    if not out.parent.exists():
        raise UsageError(f"{out}: folder {out.parent} does not exist")
    check_output_path(out)
    kind = args.output
    t0 = time.perf_counter()
    check_budget(p, size, args.allow_slow)
    scene = build_scene_for(p)
    est = check_budget(p, size, args.allow_slow, scene) if args.method == "virtual" else None
    if est is not None and est.seconds > LONG_RENDER_S:
        print(f"vfiber: rendering {out.name}: {est.summary()}", file=sys.stderr, flush=True)

    def render() -> int:
        try:
            return _render_and_write(args, p, label, size, out, kind, scene, t0)
        except ParamError as e:  # the renderer's (quality.msaa the driver cannot do): say where it came from
            if e.source is None:
                raise ParamError(e.bare, key=e.key, source=source_of(e.key, args.set, label)) from None
            raise
        except Exception as e:  # noqa: BLE001 - a frame GL cannot allocate is a size problem, said so
            better = _gl_allocation_error(e, size)
            if better is None:
                raise
            raise better from None

    if _interactive():
        return _in_child(render, out)
    try:
        # Not at a terminal: Ctrl-C raises KeyboardInterrupt once the GL driver returns; the output is
        # written whole or not at all (app.atomic), so nothing partial stays either way.
        return render()
    except KeyboardInterrupt:
        print(f"vfiber: interrupted: {out} was not written", file=sys.stderr)
        return 130


def _interactive() -> bool:
    """At a terminal, where Ctrl-C is how a person stops a render (and where nothing captures sys.stdout)."""
    try:
        return hasattr(os, "fork") and sys.stdin.isatty() and not os.environ.get("VFIBER_NO_FORK")
    except (ValueError, OSError):
        return False


def _in_child(render, out: Path) -> int:
    """Run ``render`` in a forked child and wait for it. moderngl holds the GIL while llvmpipe draws, so a
    KeyboardInterrupt in the rendering process would wait for the whole frame; the waiting parent gets it
    at once, kills the child and removes its temporary file: Ctrl-C stops cleanly, with no output."""
    import signal

    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:  # the child: Ctrl-C is the parent's to handle
        code = 2
        try:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            code = render()
        except BaseException as e:  # noqa: BLE001 - the child reports like main() and exits
            if os.environ.get("VFIBER_DEBUG"):
                import traceback
                traceback.print_exc()
            else:
                print(f"vfiber: {describe_error(e)}", file=sys.stderr)
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(code)
    try:
        _, status = os.waitpid(pid, 0)
    except KeyboardInterrupt:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        from .atomic import remove_stale_temporaries
        remove_stale_temporaries(out)
        print(f"\nvfiber: interrupted: {out} was not written", file=sys.stderr)
        return 130
    code = os.waitstatus_to_exitcode(status)
    if code < 0:
        print(f"vfiber: the render process died of signal {-code} (a GL driver crash?); {out} was not written; "
              "run vfiber doctor", file=sys.stderr)
        return 2
    return code


LONG_RENDER_S = 5.0  # renders estimated longer than this announce themselves with the estimate


def _render_and_write(args, p, label, size, out, kind, scene, t0) -> int:
    from .gl.context import create_headless
    from .render.camera import Camera
    from .render.renderer import Renderer

    wanted = {"shaded": ("color",), "id": ("ids",), "ring": ("ids",), "depth": ("geom",),
              "normal": ("geom",), "cost": ("cost",)}[kind]
    with create_headless() as gl:
        cam = Camera.from_params(p, scene)
        if args.method == "explicit":
            # the conventional baseline: every fiber stored in GPU buffers and rasterized
            from .render.explicit import ExplicitRenderer

            if kind == "cost":
                raise UsageError("--output cost counts fiber tests of the virtual method; the explicit method "
                                 "rasterizes and has none")
            explicit = (ExplicitRenderer(gl.ctx, budget_bytes=args.explicit_budget) if args.explicit_budget
                        else ExplicitRenderer(gl.ctx))
            stats = explicit.set_scene(scene, p)
            frame = explicit.render(p, cam, size, outputs=wanted)
            what = f"{stats.fibers} explicit fibers in {explicit.gpu_bytes} GPU bytes"
        else:
            renderer = Renderer(gl.ctx)
            renderer.set_scene(scene)
            frame = renderer.render_quality(p, cam, size, outputs=wanted)
            what = f"{scene.n_segments} container segments in {renderer.scene_gpu_bytes} GPU bytes"
        write_output(out, frame, kind, p)
        seconds = time.perf_counter() - t0
        print(f"wrote {out} ({kind}, {size[0]}x{size[1]}, {args.method} method, {p['quality.mode']} mode) from "
              f"{label}: {what}, {seconds:.2f} s on {gl.renderer}")
    return 0


def cmd_info(args) -> int:
    from . import reference
    from .render.renderer import scene_gpu_bytes

    p, label = resolve_params(scene_target(args), args.set)
    scene = build_scene_for(p)
    thesis, exact = reference.fiber_count(p, scene.n_segments and scene.n_guides or 0)
    lay = reference.ring_layout(p)
    lo, hi = scene.bounds()
    print(f"source           {label}")
    print(f"guides           {scene.n_guides}")
    print(f"container segs   {scene.n_segments}")
    print(f"bounding box     {np.round(lo, 4).tolist()} .. {np.round(hi, 4).tolist()}")
    print(f"rings            {lay.rings} (fibers per ring, outer to inner: "
          f"{', '.join(str(int(n)) for n in lay.n[:8])}{' ...' if lay.rings > 8 else ''})")
    print(f"fibers/container {lay.fibers_per_container}")
    print(f"fibers           {exact} exact; {thesis:.1f} by the thesis's expression 4.1")
    print(f"scene GPU bytes  {scene_gpu_bytes(scene)} (the same whatever the fiber count)")
    if hasattr(scene, "source_info"):
        for line in scene.source_info():
            print(line)
    return 0


def cmd_doctor(args) -> int:
    from .doctor import main as doctor_main

    return doctor_main()


def cmd_presets(args) -> int:
    from .presets import bundled_presets

    presets = bundled_presets()
    if not presets:
        print("no bundled presets found")
        return 1
    width = max(len(p.name) for p in presets)
    for preset in presets:
        print(f"{preset.name:<{width}}  {preset.description}")
    return 0


def cmd_view(args) -> int:
    from .viewer.app import run_viewer

    return run_viewer(args.target, script=args.script, size=parse_size(args.size))


def cmd_bench(args) -> int:
    from .bench.__main__ import main as bench_main

    return bench_main(args.rest)


def cmd_export_osl(args) -> int:
    from .export.osl import main as export_main

    return export_main(args.rest)


def make_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="vfiber", description="Hair and fur lookdev with virtual fibers.")
    sub = ap.add_subparsers(dest="command", required=True)

    def scene_args(sp):
        sp.add_argument("target", nargs="?", help="preset name or .toml file, or a groom file "
                        "(.hair .data .tfx .ply)")
        sp.add_argument("--preset", help="preset name or file (same as the positional argument)")
        sp.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override a parameter, e.g. --set fibers.rings=20 (repeatable)")

    r = sub.add_parser("render", help="render one frame offscreen to an image")
    scene_args(r)
    r.add_argument("--mode", choices=("fast", "exact", "brute"))
    r.add_argument("--size", default="640x360", help="WIDTHxHEIGHT (default 640x360)")
    r.add_argument("--output", choices=OUTPUTS, default="shaded", help="what to write (default shaded)")
    r.add_argument("-o", dest="output_file", required=True, help="output file: .png, .exr or .npy")
    r.add_argument("--method", choices=("virtual", "explicit"), default="virtual",
                   help="virtual fibers in containers (default) or the conventional explicit strands")
    r.add_argument("--allow-slow", action="store_true",
                   help="render even when the estimate says the frame takes over a minute or over 4 GiB")
    r.add_argument("--explicit-budget", type=parse_budget, default=None, metavar="BYTES",
                   help="GPU bytes the explicit method may use before it refuses (default 1GiB)")
    r.set_defaults(func=cmd_render)

    i = sub.add_parser("info", help="containers, fibers and GPU bytes of a preset or groom")
    scene_args(i)
    i.set_defaults(func=cmd_info)

    sub.add_parser("doctor", help="check the OpenGL set-up").set_defaults(func=cmd_doctor)
    sub.add_parser("presets", help="list the bundled presets").set_defaults(func=cmd_presets)

    v = sub.add_parser("view", help="open the lookdev viewer")
    v.add_argument("target", nargs="?", help="preset name or file, or a groom file")
    v.add_argument("--script", help="run a viewer script (automated sessions and tests)")
    v.add_argument("--size", default="1280x720", help="window size WIDTHxHEIGHT (default 1280x720)")
    v.set_defaults(func=cmd_view)

    b = sub.add_parser("bench", help="run the benchmark suites (see: vfiber bench --help)", add_help=False)
    b.add_argument("rest", nargs=argparse.REMAINDER)
    b.set_defaults(func=cmd_bench)

    e = sub.add_parser("export-osl", help="export a preset as an OSL shader (see: vfiber export-osl --help)",
                       add_help=False)
    e.add_argument("rest", nargs=argparse.REMAINDER)
    e.set_defaults(func=cmd_export_osl)
    return ap


PASS_THROUGH = {"bench": cmd_bench, "export-osl": cmd_export_osl}   # they parse their own options


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in PASS_THROUGH:
        args = argparse.Namespace(func=PASS_THROUGH[argv[0]], rest=argv[1:])
    else:
        args = make_parser().parse_args(argv)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("vfiber: interrupted", file=sys.stderr)
        return 130
    except Exception as e:  # noqa: BLE001 - the one place that turns errors into messages
        if os.environ.get("VFIBER_DEBUG"):
            raise
        print(f"vfiber: {describe_error(e)}", file=sys.stderr)
        return 2


def describe_error(e: Exception) -> str:
    """One line for a person; unexpected errors say so and how to see the details."""
    from .gl.context import GLContextError
    from .gl.shaders import ShaderError

    expected = (ParamError, UsageError, GLContextError, ShaderError, FileNotFoundError, PermissionError)
    try:
        from .render.explicit import ExplicitBudgetError
        expected += (ExplicitBudgetError,)
    except ImportError:
        pass
    try:
        from .scene.grooms import GroomError
        expected += (GroomError,)
    except ImportError:
        pass
    from .atomic import SaveError
    expected += (SaveError,)
    if isinstance(e, expected):
        return str(e)
    return f"unexpected error: {type(e).__name__}: {e} (run with VFIBER_DEBUG=1 for the traceback)"


if __name__ == "__main__":
    sys.exit(main())
